// OME-Zarr v2 stores (cache/formats/zarr_meta.cpp, zarr_array.cpp and every codec of zarr_codec.cpp
// behind them): the input is cut at NUL bytes (which JSON text cannot hold) into the root `.zattrs`,
// (none when empty), a `.zarray` written both as the bare array and as level "0", the `.zarray` of level "1", and the
// bytes of level 0's first chunk. The store is opened and the first chunk's box of every level read
// (level 1's chunks are missing, so they read as the fill value).
#include <cstdint>
#include <memory>
#include <vector>

#include "cache/formats/zarr_array.h"
#include "cache/formats/zarr_meta.h"
#include "core/error.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto parts = sl::fuzz::split(sl::fuzz::as_text(data, size), std::string_view("\0", 1), 4);
  const auto& dir = sl::fuzz::scratch().reset();
  const auto store = dir / "in.zarr";
  std::filesystem::create_directories(store);
  if (!parts[0].empty()) sl::fuzz::write_file(store / ".zattrs", parts[0]);  // empty: a bare array
  if (parts.size() > 1) {
    sl::fuzz::write_file(store / ".zarray", parts[1]);
    sl::fuzz::write_file(store / "0" / ".zarray", parts[1]);
  }
  if (parts.size() > 2) sl::fuzz::write_file(store / "1" / ".zarray", parts[2]);
  try {
    const sl::zarr::StoreInfo s = sl::zarr::open_store(store.string());
    const sl::zarr::Multiscale& m = s.image;
    std::uint64_t fill_bytes = 0;  // the reader holds one fill chunk per level
    for (const auto& l : m.levels) fill_bytes += l.meta.chunk_bytes();
    if (fill_bytes > sl::fuzz::kMaxVolumeBytes) return 0;
    // The chunk file is written only where the store itself lies: a level path is the input's, and
    // "../x" must not make the harness write outside its scratch directory.
    const std::string& p0 = m.levels[0].path;
    if (parts.size() > 3 && (p0 == "0" || p0 == ".")) {
      sl::fuzz::write_file(store / p0 / m.levels[0].meta.chunk_key(sl::ivec3(0)), parts[3]);
    }
    const sl::zarr::ArrayReader r(m, store.string(), std::make_shared<sl::zarr::ChunkCache>(sl::fuzz::kMaxVolumeBytes));
    for (int l = 0; l < r.levels(); ++l) {
      const auto& lv = m.levels[std::size_t(l)];
      const sl::ivec3 n = glm::min(lv.dims, lv.meta.chunk_dims());
      const std::uint64_t bytes = std::uint64_t(n.x) * std::uint64_t(n.y) * std::uint64_t(n.z) *
                                  std::uint64_t(sl::voxel_size(lv.meta.type));
      if (bytes > sl::fuzz::kMaxVolumeBytes) continue;
      std::vector<std::byte> box(bytes);
      r.read_box(l, sl::ivec3(0), n, box.data());
    }
  } catch (const sl::InputError&) {
  }
  return 0;
}
