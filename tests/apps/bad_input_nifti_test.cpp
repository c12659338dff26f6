// The bad-input corpus (bad_input_harness.h): NIfTI headers and data, plain and gzip.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>

#include "tests/apps/bad_input_harness.h"

namespace sl::bad_input {
namespace {

// A NIfTI-1 single file (.nii): the 348-byte header, the 4-byte extension flag, the voxels.
Bytes nifti_bytes(int nx, int ny, int nz, std::int16_t datatype, std::int16_t bitpix) {
  Bytes b(352, '\0');
  poke<std::int32_t>(b, 0, 348);
  const std::int16_t dim[8] = {3, std::int16_t(nx), std::int16_t(ny), std::int16_t(nz), 1, 1, 1, 1};
  for (int i = 0; i < 8; ++i) poke<std::int16_t>(b, 40 + 2 * std::size_t(i), dim[i]);
  poke<std::int16_t>(b, 70, datatype);
  poke<std::int16_t>(b, 72, bitpix);
  for (int i = 0; i < 4; ++i) poke<float>(b, 76 + 4 * std::size_t(i), 1.0f);
  poke<float>(b, 108, 352.0f);
  std::memcpy(b.data() + 344, "n+1", 4);
  Bytes data(std::size_t(nx) * std::size_t(ny) * std::size_t(nz) * std::size_t(bitpix / 8), '\0');
  for (std::size_t i = 0; i < data.size(); ++i) data[i] = char(i * 7);
  return b + data;
}

// The first bytes of a NIfTI-2 file: sizeof_hdr 540 and its magic, the rest as `b` has it.
Bytes nifti2_head(Bytes b) {
  poke<std::int32_t>(b, 0, 540);
  std::memcpy(b.data() + 4, "n+2\0\r\n\032\n", 8);
  return b;
}

std::vector<Case> nifti_cases() {
  const Bytes good = nifti_bytes(8, 8, 8, 2, 8);
  const auto edited = [&](auto fn) {
    Bytes b = good;
    fn(b);
    return file("v.nii", b);
  };
  const std::string r = kRender + "--volume v.nii";
  return {
      {"nifti", "empty file", file("v.nii", ""), r, 1, "v.nii: "},
      {"nifti", "shorter than a header", file("v.nii", good.substr(0, 100)), r, 1, "v.nii: "},
      {"nifti", "sizeof_hdr wrong", edited([](Bytes& b) { poke<std::int32_t>(b, 0, 349); }), r, 1, "v.nii: "},
      {"nifti", "NIfTI-2 sizeof_hdr on a NIfTI-1 header", edited([](Bytes& b) { poke<std::int32_t>(b, 0, 540); }), r,
       1, "v.nii: header of an unknown NIfTI version"},
      {"nifti", "NIfTI-2 header truncated", file("v.nii", nifti2_head(good).substr(0, 500)), r, 1,
       "v.nii: file is shorter than a NIfTI-2 header"},
      {"nifti", "bad magic", edited([](Bytes& b) { std::memcpy(b.data() + 344, "xyz", 4); }), r, 1, "v.nii: "},
      {"nifti", "control bytes in magic", edited([](Bytes& b) { std::memcpy(b.data() + 344, "\x07\x08\x1b", 4); }),
       r, 1, "v.nii: "},
      {"nifti", ".hdr without its .img", file("v.hdr", replaced(good.substr(0, 348), Bytes("n+1\0", 4), Bytes("ni1\0", 4))),
       kRender + "--volume v.hdr", 1, "v.hdr: header of a .hdr/.img pair"},
      {"nifti", ".img shorter than the header says", [good](const fs::path& d) {
         write_bytes(d / "v.hdr", replaced(good.substr(0, 348), Bytes("n+1\0", 4), Bytes("ni1\0", 4)));
         write_bytes(d / "v.img", good.substr(352, 100));
       }, kRender + "--volume v.hdr", 1, "v.hdr: data truncated"},
      {"nifti", "dim[0] zero", edited([](Bytes& b) { poke<std::int16_t>(b, 40, 0); }), r, 1, "v.nii: "},
      {"nifti", "dim[0] eight", edited([](Bytes& b) { poke<std::int16_t>(b, 40, 8); }), r, 1, "v.nii: "},
      {"nifti", "dim[1] zero", edited([](Bytes& b) { poke<std::int16_t>(b, 42, 0); }), r, 1, "v.nii: "},
      {"nifti", "dim[2] negative", edited([](Bytes& b) { poke<std::int16_t>(b, 44, -5); }), r, 1, "v.nii: "},
      {"nifti", "time series", edited([](Bytes& b) { poke<std::int16_t>(b, 40, 4); poke<std::int16_t>(b, 48, 3); }),
       r, 1, "v.nii: "},
      {"nifti", "float64", edited([](Bytes& b) { poke<std::int16_t>(b, 70, 64); }), r, 1, "v.nii: "},
      {"nifti", "datatype 0", edited([](Bytes& b) { poke<std::int16_t>(b, 70, 0); }), r, 1, "v.nii: "},
      {"nifti", "vox_offset zero", edited([](Bytes& b) { poke<float>(b, 108, 0.0f); }), r, 1, "v.nii: "},
      {"nifti", "vox_offset NaN", edited([](Bytes& b) { poke<float>(b, 108, NAN); }), r, 1, "v.nii: "},
      {"nifti", "vox_offset huge", edited([](Bytes& b) { poke<float>(b, 108, 1e12f); }), r, 1, "v.nii: "},
      {"nifti", "vox_offset past the end", edited([](Bytes& b) { poke<float>(b, 108, 100000.0f); }), r, 1, "v.nii: "},
      {"nifti", "data truncated", file("v.nii", good.substr(0, good.size() - 1)), r, 1, "v.nii: "},
      {"nifti", "absurd dims", edited([](Bytes& b) {
         for (int i = 1; i <= 3; ++i) poke<std::int16_t>(b, 40 + 2 * std::size_t(i), 32767);
         poke<std::int16_t>(b, 70, 16);
         poke<std::int16_t>(b, 72, 32);
       }), r, 1, "v.nii: "},
      {"nifti", "gzip corrupt", file("v.nii.gz", Bytes("\x1f\x8b\x08\x00\0\0\0\0\0\x03", 10) + Bytes(500, '\x33')),
       kRender + "--volume v.nii.gz", 1, "v.nii.gz: "},
      {"nifti", "gzip truncated", [good](const fs::path& d) {
         write_bytes(d / "g.nii", good + Bytes(4000, '\x11'));
         ASSERT_EQ(std::system(("gzip -n -c " + (d / "g.nii").string() + " > " + (d / "v.nii.gz").string()).c_str()), 0);
         fs::remove(d / "g.nii");
         truncate_to(d / "v.nii.gz", fs::file_size(d / "v.nii.gz") / 2);
       }, kRender + "--volume v.nii.gz", 1, "v.nii.gz: "},
      {"nifti", "ingest of truncated data", file("v.nii", good.substr(0, good.size() - 10)), "ingest v.nii s.zarr", 1,
       "v.nii: "},
      {"nifti", "info of a bad header", edited([](Bytes& b) { poke<std::int16_t>(b, 42, 0); }), "info v.nii", 1,
       "v.nii: "},
  };
}

TEST(BadInputCorpus, Nifti) { run_corpus(nifti_cases()); }

}  // namespace
}  // namespace sl::bad_input
