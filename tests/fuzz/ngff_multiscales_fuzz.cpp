// NGFF multiscales (cache/formats/zarr/meta.cpp: "multiscales", dataset paths, scale transforms, axes,
// the "labels" list and the max pyramid a root names): the input is cut at NUL bytes into the root
// .zattrs and labels/.zattrs of an OME-Zarr v2 store whose arrays are fixed and valid ("0": 8³ u8,
// "1": 4³, "labels/a/0": 8³ u16 with its own .zattrs). The store is opened and the first chunk's box of
// every level read. Paths that would leave the store must be refused (the store's folder sits inside
// the scratch directory beside a decoy store, so a read outside it would succeed and go unnoticed
// only if the check were missing; it is caught by the store's path check, which throws InputError).
#include "tests/fuzz/zarr_fuzz_util.h"

namespace {

std::string zarray(int n, const char* dtype) {
  return std::string("{\"zarr_format\":2,\"shape\":[") + std::to_string(n) + "," + std::to_string(n) + "," +
         std::to_string(n) + "],\"chunks\":[8,8,8],\"dtype\":\"" + dtype +
         "\",\"compressor\":null,\"fill_value\":0,\"order\":\"C\",\"filters\":null,\"dimension_separator\":\"/\"}";
}

void write_array(const std::filesystem::path& a, int n, const char* dtype, int elem) {
  sl::fuzz::write_file(a / ".zarray", zarray(n, dtype));
  sl::fuzz::write_file(a / "0" / "0" / "0", std::string(std::size_t(512 * elem), '\x05'));
}

}  // namespace

SL_FUZZ_TARGET(input) {
  const auto parts = sl::fuzz::split(input, std::string_view("\0", 1), 2);
  const auto root = sl::fuzz::scratch().reset();
  const auto store = root / "in.zarr";
  write_array(store / "0", 8, "|u1", 1);
  write_array(store / "1", 4, "|u1", 1);
  write_array(root / "decoy.zarr" / "0", 8, "|u1", 1);
  write_array(store / "labels" / "a" / "0", 8, "<u2", 2);
  sl::fuzz::write_file(store / "labels" / "a" / ".zattrs",
                       "{\"multiscales\":[{\"version\":\"0.4\",\"datasets\":[{\"path\":\"0\"}]}]}");
  sl::fuzz::write_file(store / ".zattrs", parts[0]);
  if (parts.size() > 1) sl::fuzz::write_file(store / "labels" / ".zattrs", parts[1]);
  sl::fuzz::accepted([&] {
    const sl::zarr::StoreInfo s = sl::zarr::open_store(store.string());
    for (const sl::zarr::Level& l : s.image.levels) {
      for (int i = 0; i < 3; ++i) {
        // Accepted scales are usable voxel sizes (never 0, denormal or past 1e12).
        if (!(l.scale[i] >= 1e-12f && l.scale[i] <= 1e12f)) __builtin_trap();
      }
    }
    sl::fuzz::read_first_boxes(s.image, store.string());
    if (s.labels) sl::fuzz::read_first_boxes(*s.labels, store.string());
    return true;
  });
}
