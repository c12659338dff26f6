// The bad-input corpus (bad_input_harness.h): NRRD headers, data and detached files; label volumes.
#include <gtest/gtest.h>


#include "tests/apps/bad_input_harness.h"

namespace sl::bad_input {
namespace {

std::vector<Case> nrrd_cases() {
  const Templates& t = templates();
  const std::string head = t.nrrd.substr(0, t.nrrd.find("\n\n") + 2);
  const Bytes data = t.nrrd.substr(head.size());
  const auto with_header = [&](const std::string& from, const std::string& to) {
    return file("v.nrrd", replaced(head, from, to) + data);
  };
  const std::string r = kRender + "--volume v.nrrd";
  std::vector<Case> c = {
      {"nrrd", "empty file", file("v.nrrd", ""), r, 1, "v.nrrd: "},
      {"nrrd", "bad magic", file("v.nrrd", replaced(t.nrrd, "NRRD0004", "NRRX0004")), r, 1, "v.nrrd: "},
      {"nrrd", "header without end", file("v.nrrd", head.substr(0, head.size() - 2)), r, 1, "v.nrrd: "},
      {"nrrd", "data truncated", file("v.nrrd", t.nrrd.substr(0, t.nrrd.size() - 100)), r, 1, "v.nrrd: "},
      {"nrrd", "header only", file("v.nrrd", head), r, 1, "v.nrrd: "},
      {"nrrd", "unknown type", with_header("unsigned char", "complex"), r, 1, "v.nrrd: "},
      {"nrrd", "signed type", with_header("unsigned char", "signed char"), r, 1, "v.nrrd: "},
      {"nrrd", "double type", with_header("unsigned char", "double"), r, 1, "v.nrrd: "},
      {"nrrd", "no type", with_header("type: unsigned char\n", ""), r, 1, "v.nrrd: "},
      {"nrrd", "dimension 2", with_header("dimension: 3", "dimension: 2"), r, 1, "v.nrrd: "},
      {"nrrd", "dimension 9", with_header("dimension: 3", "dimension: 9"), r, 1, "v.nrrd: "},
      {"nrrd", "size zero", with_header("sizes: 16 16 16", "sizes: 0 16 16"), r, 1, "v.nrrd: "},
      {"nrrd", "size negative", with_header("sizes: 16 16 16", "sizes: 16 -16 16"), r, 1, "v.nrrd: "},
      {"nrrd", "size overflows", with_header("sizes: 16 16 16", "sizes: 16 99999999999999999999 16"), r, 1, "v.nrrd: "},
      {"nrrd", "size not a number", with_header("sizes: 16 16 16", "sizes: 16 sixteen 16"), r, 1, "v.nrrd: "},
      {"nrrd", "two sizes", with_header("sizes: 16 16 16", "sizes: 16 16"), r, 1, "v.nrrd: "},
      {"nrrd", "absurd dims", with_header("sizes: 16 16 16", "sizes: 4000000 4000000 4000000"), r, 1, "v.nrrd: "},
      {"nrrd", "bzip2 encoding", with_header("encoding: raw", "encoding: bzip2"), r, 1, "v.nrrd: "},
      {"nrrd", "gzip encoding of raw data", with_header("encoding: raw", "encoding: gzip"), r, 1, "v.nrrd: "},
      {"nrrd", "gzip data truncated", file("v.nrrd", t.nrrd_gz.substr(0, t.nrrd_gz.size() * 2 / 3)), r, 1, "v.nrrd: "},
      {"nrrd", "gzip data flipped",
       file("v.nrrd", t.nrrd_gz.substr(0, t.nrrd_gz.size() - 40) + Bytes(40, '\x5a')), r, 1, "v.nrrd: "},
      {"nrrd", "middle endian", with_header("endian: little", "endian: middle"), r, 1, "v.nrrd: "},
      {"nrrd", "NaN spacing", with_header("spacings: 1 1 1", "spacings: nan 1 1"), r, 1, "v.nrrd: spacing"},
      {"nrrd", "negative spacing", with_header("spacings: 1 1 1", "spacings: 1 -2 1"), r, 1, "v.nrrd: spacing"},
      {"nrrd", "infinite spacing", with_header("spacings: 1 1 1", "spacings: 1 1 inf"), r, 1, "v.nrrd: "},
      {"nrrd", "zero spacing", with_header("spacings: 1 1 1", "spacings: 0 1 1"), r, 1, "v.nrrd: "},
      {"nrrd", "byte skip past the end", with_header("encoding: raw\n", "encoding: raw\nbyte skip: 100000\n"), r, 1,
       "v.nrrd: "},
      {"nrrd", "control byte in the type", with_header("unsigned char", "unsigned\x07" "char"), r, 1,
       "v.nrrd: "},
      {"nrrd", "control bytes in the encoding", with_header("encoding: raw", "encoding: r\x1b[2Jaw\x7f"), r, 1,
       "v.nrrd: "},
      {"nrrd", "detached data missing", file("v.nhdr", t.nhdr), kRender + "--volume v.nhdr", 1, "v.raw"},
      {"nrrd", "detached data short", both(file("v.nhdr", t.nhdr), file("v.raw", t.nhdr_raw.substr(0, 100))),
       kRender + "--volume v.nhdr", 1, "v.nhdr: "},
      {"nrrd", "detached data is a directory",
       [](const fs::path& d) { write_bytes(d / "v.nhdr", templates().nhdr); fs::create_directory(d / "v.raw"); },
       kRender + "--volume v.nhdr", 1, "v.raw"},
      {"nrrd", "labels of float type", both(file("v.nrrd", t.nrrd), file("l.nrrd", t.labels_f32)),
       r + " --labels l.nrrd", 1, "l.nrrd: "},
      {"nrrd", "labels of other dims",
       both(file("v.nrrd", t.nrrd), file("l.nrrd", replaced(t.labels16, "sizes: 16 16 16", "sizes: 16 16 8").substr(
                                                       0, t.labels16.size() - 16 * 16 * 8 * 2))),
       r + " --labels l.nrrd", 1, "l.nrrd: "},
      {"nrrd", "label id 0xFFFFFFFF", [](const fs::path& d) {
         write_bytes(d / "v.nrrd", templates().nrrd);
         Volume lab(VolumeDesc{{16, 16, 16}, vec3(1.0f), VoxelType::U32});
         lab.as<std::uint32_t>()[100] = 0xFFFFFFFFu;
         write_nrrd((d / "l.nrrd").string(), lab);
       }, r + " --labels l.nrrd --mode labels", 1, "l.nrrd: largest label id 4294967295"},
      {"nrrd", "a device as the volume", kNothing, kRender + "--volume /dev/zero", 1, "/dev/zero: is a character device, not a regular file"},
      {"nrrd", "a device as the data file", file("v.nhdr", replaced(t.nhdr, "data file: v.raw", "data file: /dev/zero")),
       kRender + "--volume v.nhdr", 1, "v.nhdr: data file '/dev/zero'"},
      {"nrrd", "info of a truncated file", file("v.nrrd", head.substr(0, 20)), "info v.nrrd", 1, "v.nrrd: "},
      {"nrrd", "info --stats of truncated data", file("v.nrrd", t.nrrd.substr(0, t.nrrd.size() - 1)),
       "info --stats v.nrrd", 1, "v.nrrd: "},
      {"nrrd", "ingest of truncated data", file("v.nrrd", t.nrrd.substr(0, t.nrrd.size() - 1)),
       "ingest v.nrrd s.zarr", 1, "v.nrrd: "},
      {"nrrd", "bench of a bad file", file("v.nrrd", "NRRD0004\n\n"), "bench --size 8x8 --orbit 1 --volume v.nrrd", 1,
       "v.nrrd: "},
  };
  // Dims that fit the format but not this machine: refused from the header, never allocated.
  const std::uint64_t side = 4096, z = t.phys_bytes / (side * side) + 1;
  // Ingest streams, but holds a layer of chunk x X x Y voxels per level: 100000² slices cannot fit.
  c.push_back({"nrrd", "ingest layers larger than memory", [](const fs::path& d) {
                 const std::string h = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 100000 100000 2\nencoding: raw\n\n";
                 write_bytes(d / "v.nrrd", h);
                 fs::resize_file(d / "v.nrrd", h.size() + 20000000000ull);  // sparse: no disk used
               },
               "ingest v.nrrd s.zarr", 1, "v.nrrd: ingest would need"});
  c.push_back({"nrrd", "more voxels than memory",
               with_header("sizes: 16 16 16", "sizes: 4096 4096 " + std::to_string(z)), r, 1,
               "v.nrrd: 4096x4096x" + std::to_string(z) + " u8 needs"});
  return c;
}

TEST(BadInputCorpus, Nrrd) { run_corpus(nrrd_cases()); }

}  // namespace
}  // namespace sl::bad_input
