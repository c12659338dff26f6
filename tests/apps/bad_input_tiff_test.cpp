// The bad-input corpus (bad_input_harness.h): TIFF stacks.
#include <gtest/gtest.h>


#include "tests/apps/bad_input_harness.h"

namespace sl::bad_input {
namespace {

// A baseline little-endian TIFF, one strip per page.
struct TiffPage {
  std::uint32_t w = 8, h = 8;
  std::uint16_t bits = 8, spp = 1, compression = 1, sample_format = 1;
  std::int64_t strip_offset = -1;  // -1: where the data are
  std::int64_t strip_bytes = -1;   // -1: the data's size
};
Bytes tiff_bytes(const std::vector<TiffPage>& pages) {
  Bytes b("II*\0\x08\0\0\0", 8);
  constexpr int kEntries = 10;
  for (std::size_t k = 0; k < pages.size(); ++k) {
    const TiffPage& p = pages[k];
    const std::size_t ifd = b.size(), data_at = ifd + 2 + 12 * kEntries + 4;
    // An absurd page keeps its header sizes but carries no data (the reader must refuse it first).
    const std::size_t voxels = std::size_t(p.w) * p.h * p.spp;
    const std::size_t data_size = voxels > (1u << 20) ? 0 : voxels * std::max<std::uint16_t>(p.bits / 8, 1);
    Bytes e(2 + 12 * kEntries + 4, '\0');
    poke<std::uint16_t>(e, 0, kEntries);
    int n = 0;
    const auto entry = [&](std::uint16_t tag, std::uint16_t type, std::uint32_t value) {
      const std::size_t o = 2 + 12 * std::size_t(n++);
      poke<std::uint16_t>(e, o, tag);
      poke<std::uint16_t>(e, o + 2, type);
      poke<std::uint32_t>(e, o + 4, 1);
      if (type == 3) {
        poke<std::uint16_t>(e, o + 8, std::uint16_t(value));
      } else {
        poke<std::uint32_t>(e, o + 8, value);
      }
    };
    entry(256, 4, p.w);
    entry(257, 4, p.h);
    entry(258, 3, p.bits);
    entry(259, 3, p.compression);
    entry(262, 3, 1);
    entry(273, 4, std::uint32_t(p.strip_offset < 0 ? std::int64_t(data_at) : p.strip_offset));
    entry(277, 3, p.spp);
    entry(278, 4, p.h);
    entry(279, 4, std::uint32_t(p.strip_bytes < 0 ? std::int64_t(data_size) : p.strip_bytes));
    entry(339, 3, p.sample_format);
    const bool last = k + 1 == pages.size();
    poke<std::uint32_t>(e, 2 + 12 * kEntries, last ? 0u : std::uint32_t(data_at + data_size));
    b += e;
    for (std::size_t i = 0; i < data_size; ++i) b.push_back(char(i * 3));
  }
  return b;
}

std::vector<Case> tiff_cases() {
  const auto one = [](TiffPage p) { return file("v.tif", tiff_bytes({p})); };
  const Bytes good = tiff_bytes({TiffPage{}, TiffPage{}, TiffPage{}});
  const std::string r = kRender + "--volume v.tif";
  return {
      {"tiff", "empty file", file("v.tif", ""), r, 1, "v.tif"},
      {"tiff", "bad magic", file("v.tif", replaced(good, "II*", "IJ*")), r, 1, "v.tif"},
      {"tiff", "header only", file("v.tif", good.substr(0, 8)), r, 1, "v.tif"},
      {"tiff", "truncated in the first directory", file("v.tif", good.substr(0, 40)), r, 1, "v.tif"},
      {"tiff", "directory offset past the end", file("v.tif", replaced(good, Bytes("II*\0\x08", 5), Bytes("II*\0\xf0", 5))),
       r, 1, "v.tif"},
      {"tiff", "data truncated", file("v.tif", good.substr(0, good.size() - 10)), r, 1, "v.tif"},
      {"tiff", "zero width", one(TiffPage{.w = 0}), r, 1, "v.tif"},
      {"tiff", "12 bits", one(TiffPage{.bits = 12}), r, 1, "v.tif"},
      {"tiff", "RGB", one(TiffPage{.spp = 3}), r, 1, "v.tif"},
      {"tiff", "signed samples", one(TiffPage{.bits = 16, .sample_format = 2}), r, 1, "v.tif"},
      {"tiff", "16-bit float", one(TiffPage{.bits = 16, .sample_format = 3}), r, 1, "v.tif"},
      {"tiff", "unknown compression", one(TiffPage{.compression = 34712}), r, 1, "v.tif"},
      {"tiff", "strip offset past the end", one(TiffPage{.strip_offset = 1 << 20}), r, 1, "v.tif"},
      {"tiff", "directory chain loops", [](const fs::path& d) {
         Bytes b = tiff_bytes({TiffPage{}, TiffPage{}});
         poke<std::uint32_t>(b, 8 + 2 + 12 * 10 + 8 * 8 + 2 + 12 * 10, 8);  // page 2's next IFD: page 1
         write_bytes(d / "v.tif", b);
       }, r, 1, "v.tif"},
      {"tiff", "pages of different sizes", file("v.tif", tiff_bytes({TiffPage{}, TiffPage{.w = 9}})), r, 1, "v.tif"},
      {"tiff", "absurd size", one(TiffPage{.w = 0x7fffffff, .h = 0x7fffffff}), r, 1, "v.tif"},
      {"tiff", "slices of different sizes",
       [](const fs::path& d) {
         fs::create_directory(d / "s");
         write_bytes(d / "s" / "a.tif", tiff_bytes({TiffPage{}}));
         write_bytes(d / "s" / "b.tif", tiff_bytes({TiffPage{.w = 6}}));
       }, kRender + "--volume s", 1, "b.tif"},
      {"tiff", "slices of different types",
       [](const fs::path& d) {
         fs::create_directory(d / "s");
         write_bytes(d / "s" / "a.tif", tiff_bytes({TiffPage{}}));
         write_bytes(d / "s" / "b.tif", tiff_bytes({TiffPage{.bits = 16}}));
       }, kRender + "--volume s", 1, "b.tif"},
      {"tiff", "folder without slices", [](const fs::path& d) { fs::create_directory(d / "s"); }, kRender + "--volume s",
       1, "s: "},
      {"tiff", "a slice that is not a TIFF",
       [](const fs::path& d) {
         fs::create_directory(d / "s");
         write_bytes(d / "s" / "a.tif", tiff_bytes({TiffPage{}}));
         write_bytes(d / "s" / "b.tif", "not a tiff at all");
       }, kRender + "--volume s", 1, "b.tif"},
      {"tiff", "ingest of truncated data", file("v.tif", good.substr(0, good.size() - 10)), "ingest v.tif s.zarr", 1,
       "v.tif"},
  };
}

TEST(BadInputCorpus, Tiff) { run_corpus(tiff_cases()); }

}  // namespace
}  // namespace sl::bad_input
