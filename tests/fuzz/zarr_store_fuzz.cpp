// OME-Zarr v2 stores (cache/formats/zarr/: meta.cpp, v2_array.cpp, array.cpp and every codec of
// compressor.cpp behind them): the input is cut at NUL bytes (which JSON text cannot hold) into the root `.zattrs`
// (none when empty), a `.zarray` written both as the bare array and as level "0", the `.zarray` of
// level "1", and the bytes of level 0's first chunk. The store is opened and the first chunk's box of
// every level read (level 1's chunks are missing, so they read as the fill value).
#include "tests/fuzz/zarr_fuzz_util.h"

SL_FUZZ_TARGET(input) {
  const auto parts = sl::fuzz::split(input, std::string_view("\0", 1), 4);
  const auto store = sl::fuzz::scratch().reset() / "in.zarr";
  std::filesystem::create_directories(store);
  if (!parts[0].empty()) sl::fuzz::write_file(store / ".zattrs", parts[0]);  // empty: a bare array
  if (parts.size() > 1) {
    sl::fuzz::write_file(store / ".zarray", parts[1]);
    sl::fuzz::write_file(store / "0" / ".zarray", parts[1]);
  }
  if (parts.size() > 2) sl::fuzz::write_file(store / "1" / ".zarray", parts[2]);
  sl::fuzz::accepted([&] {
    const sl::zarr::StoreInfo s = sl::zarr::open_store(store.string());
    const sl::zarr::Multiscale& m = s.image;
    // The chunk file is written only where the store itself lies: a level path is the input's, and
    // "../x" must not make the harness write outside its scratch directory.
    const std::string& p0 = m.levels[0].path;
    if (parts.size() > 3 && (p0 == "0" || p0 == ".")) {
      sl::fuzz::write_file(store / p0 / m.levels[0].meta.chunk_key(sl::ivec3(0)), parts[3]);
    }
    sl::fuzz::read_first_boxes(m, store.string());
    return true;
  });
}
