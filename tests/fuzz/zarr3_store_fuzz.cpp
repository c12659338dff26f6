// OME-Zarr v3 stores (NGFF 0.5; in cache/formats/zarr/: meta.cpp's group and "ome" attributes,
// v3_array.cpp's array zarr.json, v3_codec.cpp's codec chains, v3_chunk.cpp's shard reads): the input is cut
// at NUL bytes into the root zarr.json, level "0"'s zarr.json (with an empty root: written as the
// root, a bare array), level "1"'s zarr.json and the bytes of level 0's first chunk (its first shard
// when sharded, index included). The store is opened and the first chunk's box of every level read.
#include "tests/fuzz/zarr_fuzz_util.h"

#include "cache/formats/zarr/v3_codec.h"

SL_FUZZ_TARGET(input) {
  const auto parts = sl::fuzz::split(input, std::string_view("\0", 1), 4);
  const auto store = sl::fuzz::scratch().reset() / "in.zarr";
  std::filesystem::create_directories(store);
  if (parts[0].empty()) {
    if (parts.size() > 1) sl::fuzz::write_file(store / "zarr.json", parts[1]);
  } else {
    sl::fuzz::write_file(store / "zarr.json", parts[0]);
    if (parts.size() > 1) sl::fuzz::write_file(store / "0" / "zarr.json", parts[1]);
  }
  if (parts.size() > 2) sl::fuzz::write_file(store / "1" / "zarr.json", parts[2]);
  sl::fuzz::accepted([&] {
    const sl::zarr::StoreInfo s = sl::zarr::open_store(store.string());
    const sl::zarr::Multiscale& m = s.image;
    const sl::zarr::Level& l0 = m.levels[0];
    // Only where the store itself lies (a level path is the input's: "../x" must stay out).
    if (parts.size() > 3 && l0.meta.v3 && (l0.path == "0" || l0.path == ".")) {
      const std::string key = l0.meta.v3->key(std::vector<std::int64_t>(std::size_t(l0.meta.ndim()), 0));
      sl::fuzz::write_file(store / l0.path / key, parts[3]);
    }
    sl::fuzz::read_first_boxes(m, store.string());
    return true;
  });
}
