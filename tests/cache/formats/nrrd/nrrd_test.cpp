#include "cache/formats/nrrd/nrrd.h"

#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <functional>
#include <set>
#include <string>
#include <tuple>

#include <unistd.h>

#include "core/util/error.h"
#include "tests/test_util.h"

namespace sl {
namespace {

namespace fs = std::filesystem;
using test::read_text;
using test::scratch_dir;
using test::write_text;

// Values that fill every byte of the type, so a byte-order or offset slip cannot go unnoticed.
Volume pattern_volume(VoxelType type, ivec3 dims = {7, 5, 3}, vec3 spacing = {0.5f, 1.25f, 2.0f}) {
  Volume v(VolumeDesc{dims, spacing, type});
  int i = 0;
  for (int z = 0; z < dims.z; ++z) {
    for (int y = 0; y < dims.y; ++y) {
      for (int x = 0; x < dims.x; ++x, ++i) {
        switch (type) {
          case VoxelType::U8: v.set(x, y, z, float((i * 37 + 11) % 256)); break;
          case VoxelType::U16: v.set(x, y, z, float((i * 4099 + 258) % 65536)); break;
          case VoxelType::U32: v.as<std::uint32_t>()[i] = 0x01020304u * std::uint32_t(i + 1) + 0x80000000u; break;
          case VoxelType::F32: v.set(x, y, z, float(i) * 0.37f - 5.0f); break;
        }
      }
    }
  }
  return v;
}

void expect_same(const Volume& a, const Volume& b) {
  ASSERT_EQ(a.dims(), b.dims());
  EXPECT_EQ(a.type(), b.type());
  EXPECT_EQ(a.desc().spacing, b.desc().spacing);
  ASSERT_EQ(a.desc().byte_size(), b.desc().byte_size());
  EXPECT_EQ(std::memcmp(a.data(), b.data(), a.desc().byte_size()), 0);
}

std::set<std::string> listing(const fs::path& dir) {
  std::set<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.insert(e.path().filename().string());
  return names;
}

// Runs fn, which must throw InputError whose message names `file` and contains `phrase`.
void expect_input_error(const std::function<void()>& fn, const std::string& file, const std::string& phrase) {
  try {
    fn();
    ADD_FAILURE() << "no InputError; expected one containing '" << phrase << "'";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(file), std::string::npos) << what;
    EXPECT_NE(what.find(phrase), std::string::npos) << "'" << phrase << "' not in: " << what;
  }
}

// ---- round trips ---------------------------------------------------------------------------------

using RoundTripParam = std::tuple<VoxelType, bool /*gzip*/, bool /*detached*/>;
class NrrdRoundTrip : public ::testing::TestWithParam<RoundTripParam> {};

TEST_P(NrrdRoundTrip, ReadsBackWhatWasWritten) {
  const auto [type, gzip, detached] = GetParam();
  const fs::path dir = scratch_dir();
  const fs::path path = dir / (detached ? "vol.nhdr" : "vol.nrrd");
  const Volume v = pattern_volume(type);
  write_nrrd(path.string(), v, gzip);
  expect_same(read_nrrd(path.string()), v);

  const VolumeDesc d = read_nrrd_header(path.string());
  EXPECT_EQ(d.dims, v.dims());
  EXPECT_EQ(d.type, type);
  EXPECT_EQ(d.spacing, v.desc().spacing);

  // Exactly the promised files, no temporaries left behind.
  std::set<std::string> expected{path.filename().string()};
  if (detached) expected.insert(gzip ? "vol.raw.gz" : "vol.raw");
  EXPECT_EQ(listing(dir), expected);
  const std::string header = read_text(path);
  EXPECT_EQ(header.rfind("NRRD0004\n", 0), 0u);
  EXPECT_NE(header.find("dimension: 3\n"), std::string::npos);
  EXPECT_NE(header.find("endian: little\n"), std::string::npos);
  EXPECT_NE(header.find(gzip ? "encoding: gzip\n" : "encoding: raw\n"), std::string::npos);
  if (detached) {
    EXPECT_NE(header.find(gzip ? "data file: vol.raw.gz\n" : "data file: vol.raw\n"), std::string::npos);
    if (!gzip) {
      EXPECT_EQ(fs::file_size(dir / "vol.raw"), v.desc().byte_size());
    }
  } else if (!gzip) {
    // Attached raw: header, blank line, then exactly the voxels.
    const auto blank = header.find("\n\n");
    ASSERT_NE(blank, std::string::npos);
    EXPECT_EQ(header.size(), blank + 2 + v.desc().byte_size());
  }
}

INSTANTIATE_TEST_SUITE_P(AllTypesEncodingsForms, NrrdRoundTrip,
                         ::testing::Combine(::testing::Values(VoxelType::U8, VoxelType::U16, VoxelType::U32,
                                                              VoxelType::F32),
                                            ::testing::Bool(), ::testing::Bool()),
                         [](const auto& info) {
                           return std::string(to_string(std::get<0>(info.param))) +
                                  (std::get<1>(info.param) ? "_gzip" : "_raw") +
                                  (std::get<2>(info.param) ? "_detached" : "_attached");
                         });

TEST(Nrrd, RoundTripsALargerNonPowerOfTwoVolume) {
  const fs::path p = scratch_dir() / "big.nrrd";
  const Volume v = pattern_volume(VoxelType::U16, {67, 33, 129}, {1.0f, 1.0f, 0.1f});
  write_nrrd(p.string(), v, true);
  expect_same(read_nrrd(p.string()), v);
}

TEST(Nrrd, OverwritesAnExistingFile) {
  const fs::path p = scratch_dir() / "v.nrrd";
  write_nrrd(p.string(), pattern_volume(VoxelType::F32, {9, 9, 9}));
  const Volume small = pattern_volume(VoxelType::U8, {2, 3, 4});
  write_nrrd(p.string(), small);
  expect_same(read_nrrd(p.string()), small);
}

// ---- hand-written inputs -------------------------------------------------------------------------

std::string header(const std::string& type, const std::string& sizes, const std::string& extra = "") {
  return "NRRD0005\ntype: " + type + "\ndimension: 3\nsizes: " + sizes + "\n" + extra;
}

TEST(Nrrd, ReadsBigEndianData) {
  const fs::path dir = scratch_dir();
  {  // u16 0x0102, 0xA0B0 stored big-endian
    const fs::path p = dir / "be16.nrrd";
    write_text(p, header("ushort", "2 1 1", "endian: big\nencoding: raw\n\n") +
                      std::string("\x01\x02\xA0\xB0", 4));
    const Volume v = read_nrrd(p.string());
    EXPECT_EQ(v.label(0, 0, 0), 0x0102u);
    EXPECT_EQ(v.label(1, 0, 0), 0xA0B0u);
  }
  {  // u32 and f32 (1.5f = 0x3FC00000, -2.0f = 0xC0000000)
    const fs::path p = dir / "be32.nhdr";
    write_text(p, header("uint32", "1 1 2", "endian: big\nencoding: raw\ndata file: be32.raw\n"));
    write_text(dir / "be32.raw", std::string("\x01\x02\x03\x04\xFF\x00\x00\x01", 8));
    const Volume v = read_nrrd(p.string());
    EXPECT_EQ(v.label(0, 0, 0), 0x01020304u);
    EXPECT_EQ(v.label(0, 0, 1), 0xFF000001u);
    const fs::path pf = dir / "bef.nrrd";
    write_text(pf, header("float", "2 1 1", "endian: big\nencoding: raw\n\n") +
                       std::string("\x3F\xC0\x00\x00\xC0\x00\x00\x00", 8));
    const Volume f = read_nrrd(pf.string());
    EXPECT_EQ(f.value(0, 0, 0), 1.5f);
    EXPECT_EQ(f.value(1, 0, 0), -2.0f);
  }
}

TEST(Nrrd, AcceptsEveryTypeSpelling) {
  const fs::path p = scratch_dir() / "t.nrrd";
  const std::pair<const char*, VoxelType> cases[] = {
      {"uchar", VoxelType::U8},           {"unsigned char", VoxelType::U8},
      {"uint8", VoxelType::U8},           {"uint8_t", VoxelType::U8},
      {"ushort", VoxelType::U16},         {"unsigned short", VoxelType::U16},
      {"unsigned short int", VoxelType::U16}, {"uint16", VoxelType::U16},
      {"uint16_t", VoxelType::U16},       {"uint", VoxelType::U32},
      {"unsigned int", VoxelType::U32},   {"uint32", VoxelType::U32},
      {"uint32_t", VoxelType::U32},       {"float", VoxelType::F32},
      {"Unsigned  Short", VoxelType::U16}};
  for (const auto& [name, type] : cases) {
    write_text(p, header(name, "1 1 1", "encoding: raw\n\n") + std::string(4, '\0'));
    EXPECT_EQ(read_nrrd(p.string()).type(), type) << name;
  }
}

TEST(Nrrd, SpacingFromSpacingsAndSpaceDirections) {
  const fs::path p = scratch_dir() / "s.nrrd";
  const std::string data(8, '\x7f');
  write_text(p, header("uchar", "2 2 2", "spacings: 0.5 1 3\nencoding: raw\n\n") + data);
  EXPECT_EQ(read_nrrd_header(p.string()).spacing, vec3(0.5f, 1.0f, 3.0f));
  // NaN (unknown) and negative spacings are refused, not replaced by 1 or |s|.
  for (const char* bad : {"0.5 nan 3", "0.5 1 -3", "-0.5 1 1"}) {
    write_text(p, header("uchar", "2 2 2", std::string("spacings: ") + bad + "\nencoding: raw\n\n") + data);
    expect_input_error([&] { read_nrrd_header(p.string()); }, p.string(), "must be a positive number");
  }

  write_text(p, header("uchar", "2 2 2",
                       "space: left-posterior-superior\n"
                       "space directions: (0,0.6,0.8) (2,0,0) (0,0,-0.25)\n"
                       "space origin: (10,20,30)\nencoding: raw\n\n") + data);
  const Volume v = read_nrrd(p.string());
  EXPECT_NEAR(v.desc().spacing.x, 1.0f, 1e-6f);
  EXPECT_EQ(v.desc().spacing.y, 2.0f);
  EXPECT_EQ(v.desc().spacing.z, 0.25f);
  EXPECT_EQ(v.value(1, 1, 1), 127.0f);

  write_text(p, header("uchar", "2 2 2", "encoding: raw\n\n") + data);
  EXPECT_EQ(read_nrrd_header(p.string()).spacing, vec3(1.0f));  // default
}

TEST(Nrrd, ToleratesCommentsKeyValuesUnknownFieldsCrlfAndOldMagic) {
  const fs::path dir = scratch_dir();
  fs::create_directories(dir / "sub");
  write_text(dir / "sub" / "d.raw", std::string("junk\nmore junk\n") + "\x05\x06\x07\x08\x09\x0a");
  write_text(dir / "h.nhdr",
             "NRRD0001\r\n# a comment: with colon\r\nTYPE: unsigned char\r\nDimension: 3\r\n"
             "content: test:=not a pair\r\nmy key:=my value\r\nkinds: domain domain domain\r\n"
             "sizes: 3 2 1\r\nEncoding: RAW\r\nlineskip: 2\r\nbyte skip: 0\r\ndatafile: sub/d.raw\r\n");
  const Volume v = read_nrrd((dir / "h.nhdr").string());
  ASSERT_EQ(v.dims(), ivec3(3, 2, 1));
  EXPECT_EQ(v.value(0, 0, 0), 5.0f);
  EXPECT_EQ(v.value(2, 1, 0), 10.0f);
}

TEST(Nrrd, ByteSkipAndTrailingBytes) {
  const fs::path dir = scratch_dir();
  write_text(dir / "a.nrrd", header("uchar", "2 1 1", "byte skip: 3\nencoding: raw\n\n") + "xyz\x01\x02trailing");
  const Volume a = read_nrrd((dir / "a.nrrd").string());
  EXPECT_EQ(a.value(0, 0, 0), 1.0f);
  EXPECT_EQ(a.value(1, 0, 0), 2.0f);
  // -1: the data are the file's last bytes, whatever precedes them.
  write_text(dir / "b.nhdr", header("uchar", "2 1 1", "byte skip: -1\nencoding: raw\ndata file: b.raw\n"));
  write_text(dir / "b.raw", "some preamble\x03\x04");
  const Volume b = read_nrrd((dir / "b.nhdr").string());
  EXPECT_EQ(b.value(0, 0, 0), 3.0f);
  EXPECT_EQ(b.value(1, 0, 0), 4.0f);
}

TEST(Nrrd, AbsoluteDataFilePath) {
  const fs::path dir = scratch_dir();
  write_text(dir / "abs.raw", "\x2a");
  write_text(dir / "abs.nhdr",
             header("uchar", "1 1 1", "encoding: raw\ndata file: " + (dir / "abs.raw").string() + "\n"));
  EXPECT_EQ(read_nrrd((dir / "abs.nhdr").string()).value(0, 0, 0), 42.0f);
}

// ---- bad inputs ----------------------------------------------------------------------------------

struct BadHeader {
  const char* name;
  std::string text;
  const char* phrase;
};

TEST(NrrdErrors, BadHeadersNameTheFileAndTheProblem) {
  const fs::path dir = scratch_dir();
  const std::string ok_tail = "encoding: raw\n\n" + std::string(8, '\0');
  const BadHeader cases[] = {
      {"empty", "", "not a NRRD file"},
      {"png", "\x89PNG\r\n\x1a\n....", "not a NRRD file"},
      {"text", "hello world\n", "not a NRRD file"},
      {"version", "NRRD0009\ntype: uchar\n", "unsupported NRRD magic 'NRRD0009'"},
      {"no_sizes", "NRRD0004\ntype: uchar\ndimension: 3\n" + ok_tail, "missing required field 'sizes'"},
      {"no_type", "NRRD0004\nsizes: 2 2 2\ndimension: 3\n" + ok_tail, "missing required field 'type'"},
      {"no_encoding", header("uchar", "2 2 2") + "\n" + std::string(8, '\0'), "missing required field 'encoding'"},
      {"no_dimension", "NRRD0004\ntype: uchar\nsizes: 2 2 2\n" + ok_tail, "missing required field 'dimension'"},
      {"unknown_type", header("quux", "2 2 2") + ok_tail, "unknown type 'quux'"},
      {"double", header("double", "2 2 2") + ok_tail, "type 'double' is not supported"},
      {"signed", header("short", "2 2 2") + ok_tail, "type 'short' is not supported"},
      {"unknown_encoding", header("uchar", "2 2 2", "encoding: zip\n\n"), "unknown encoding 'zip'"},
      {"ascii", header("uchar", "2 2 2", "encoding: ascii\n\n1 2 3"), "encoding 'ascii' is not supported"},
      {"dim2", "NRRD0004\ntype: uchar\ndimension: 2\nsizes: 2 2\n" + ok_tail, "dimension is 2"},
      {"dim4", "NRRD0004\ntype: uchar\ndimension: 4\nsizes: 1 2 2 2\n" + ok_tail, "dimension is 4"},
      {"dimx", "NRRD0004\ntype: uchar\ndimension: three\nsizes: 2 2 2\n" + ok_tail, "not an integer"},
      {"sizes_count", header("uchar", "2 2") + ok_tail, "expected 3"},
      {"size_zero", header("uchar", "2 0 2") + ok_tail, "axis 1 is 0 (must be positive)"},
      {"size_negative", header("uchar", "-4 2 2") + ok_tail, "axis 0 is -4 (must be positive)"},
      {"size_text", header("uchar", "2 two 2") + ok_tail, "size 'two' is not an integer"},
      {"size_absurd", header("uchar", "2 2 99999999999") + ok_tail, "absurdly large"},
      {"size_overflow", header("uint", "2000000000 2000000000 2000000000") + ok_tail, "overflows 64 bits"},
      {"endian", header("ushort", "2 2 2", "endian: middle\n") + ok_tail, "unknown endian 'middle'"},
      {"spacing", header("uchar", "2 2 2", "spacings: 1 x 1\n") + ok_tail, "spacing 'x' is not a number"},
      {"spacing_zero", header("uchar", "2 2 2", "spacings: 1 0 1\n") + ok_tail, "spacing along axis 1"},
      {"directions", header("uchar", "2 2 2", "space directions: (1,0,0) (0,1,0\n") + ok_tail, "space directions"},
      {"not_a_field", header("uchar", "2 2 2", "this line has no colon\n") + ok_tail, "not a 'field: value' pair"},
      {"no_blank", header("uchar", "2 2 2", "encoding: raw\n"), "no blank line"},
      {"list", header("uchar", "2 2 2", "encoding: raw\ndata file: LIST\na.raw\n"), "multi-file"},
      {"list_subdim", header("uchar", "2 2 2", "encoding: raw\ndata file: LIST 2\na.raw\nb.raw\n"), "multi-file"},
      {"format", header("uchar", "2 2 2", "encoding: raw\ndata file: s%03d.raw 1 2 1\n"), "multi-file"},
      {"skip_gzip", header("uchar", "2 2 2", "byte skip: -1\nencoding: gzip\n\n"), "only allowed with raw"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.name);
    const fs::path p = dir / (std::string(c.name) + ".nrrd");
    write_text(p, c.text);
    expect_input_error([&] { read_nrrd(p.string()); }, p.string(), c.phrase);
    expect_input_error([&] { read_nrrd_header(p.string()); }, p.string(), c.phrase);
  }
}

TEST(NrrdErrors, TooLargeForMemoryButDescribable) {
  const fs::path p = scratch_dir() / "huge.nhdr";
  write_text(p, header("ushort", "100000 100000 100000", "encoding: raw\ndata file: huge.raw\n"));
  EXPECT_EQ(read_nrrd_header(p.string()).dims, ivec3(100000));  // `info` can describe it
  expect_input_error([&] { read_nrrd(p.string()); }, p.string(), "exceed the in-memory limit");
}

TEST(NrrdErrors, MissingFileAndDirectory) {
  const fs::path dir = scratch_dir();
  const std::string missing = (dir / "nope.nrrd").string();
  expect_input_error([&] { read_nrrd(missing); }, missing, "file not found");
  expect_input_error([&] { read_nrrd_header(missing); }, missing, "file not found");
  expect_input_error([&] { read_nrrd(dir.string()); }, dir.string(), "is a directory");
}

TEST(NrrdErrors, MissingOrTruncatedData) {
  const fs::path dir = scratch_dir();
  const fs::path h = dir / "d.nhdr";
  write_text(h, header("ushort", "5 7 3", "endian: little\nencoding: raw\ndata file: d.raw\n"));
  expect_input_error([&] { read_nrrd(h.string()); }, h.string(), "data file '");
  expect_input_error([&] { read_nrrd(h.string()); }, h.string(), "d.raw': file not found");
  EXPECT_EQ(read_nrrd_header(h.string()).dims, ivec3(5, 7, 3));  // the header alone is fine

  write_text(dir / "d.raw", std::string(50, '\1'));
  expect_input_error([&] { read_nrrd(h.string()); }, h.string(),
                     "data truncated: expected 210 bytes of raw data, found 50");

  const fs::path a = dir / "a.nrrd";
  write_text(a, header("float", "2 2 2", "encoding: raw\n\n") + std::string(31, '\0'));
  expect_input_error([&] { read_nrrd(a.string()); }, a.string(), "expected 32 bytes of raw data, found 31");
  write_text(a, header("float", "2 2 2", "encoding: raw\n\n"));
  expect_input_error([&] { read_nrrd(a.string()); }, a.string(), "found 0");
  write_text(a, header("uchar", "2 1 1", "line skip: 3\nencoding: raw\n\n") + "one\ntwo\n");
  expect_input_error([&] { read_nrrd(a.string()); }, a.string(), "within the skipped lines");
}

// Returns the attached gzip file's header and compressed payload, split at the blank line.
std::pair<std::string, std::string> split_attached(const fs::path& p) {
  const std::string s = read_text(p);
  const auto blank = s.find("\n\n");
  return {s.substr(0, blank + 2), s.substr(blank + 2)};
}

std::string replace(std::string s, const std::string& from, const std::string& to) {
  const auto at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return at == std::string::npos ? s : s.replace(at, from.size(), to);
}

TEST(NrrdErrors, BadGzipData) {
  const fs::path dir = scratch_dir();
  const fs::path p = dir / "g.nrrd";
  write_nrrd(p.string(), pattern_volume(VoxelType::U16, {16, 16, 16}), true);
  const auto [head, zdata] = split_attached(p);
  ASSERT_GT(zdata.size(), 40u);

  std::string corrupt = zdata;
  for (std::size_t i = 20; i < 30; ++i) corrupt[i] = char(~corrupt[i]);
  write_text(p, head + corrupt);
  expect_input_error([&] { read_nrrd(p.string()); }, p.string(), "gzip data are corrupt");

  write_text(p, head + "this is not gzip at all, just text that goes on");
  expect_input_error([&] { read_nrrd(p.string()); }, p.string(), "gzip data are corrupt");

  write_text(p, head + zdata.substr(0, zdata.size() / 2));
  expect_input_error([&] { read_nrrd(p.string()); }, p.string(), "gzip data truncated: expected 8192 bytes");

  write_text(p, head + zdata.substr(0, zdata.size() - 4));  // all voxels, but no checksum/length
  expect_input_error([&] { read_nrrd(p.string()); }, p.string(), "ends before its checksum");

  write_text(p, replace(head, "sizes: 16 16 16", "sizes: 16 16 8") + zdata);  // decompresses to too much
  expect_input_error([&] { read_nrrd(p.string()); }, p.string(), "more than the expected 4096 bytes");

  write_text(p, replace(head, "sizes: 16 16 16", "sizes: 16 16 17") + zdata);  // too little
  expect_input_error([&] { read_nrrd(p.string()); }, p.string(),
                     "expected 8704 bytes after decompression, found 8192");
}

// Damaged files (bytes overwritten anywhere, or cut short) are either still readable or rejected with
// InputError; never another exception, a crash or (under the sanitizers) a memory error.
RC_GTEST_PROP(NrrdProperty, DamagedFilesFailOnlyWithInputError, ()) {
  const fs::path p = scratch_dir() / "damaged.nrrd";
  const auto type = *rc::gen::element(VoxelType::U8, VoxelType::U16, VoxelType::U32, VoxelType::F32);
  const ivec3 dims(*rc::gen::inRange(1, 9), *rc::gen::inRange(1, 9), *rc::gen::inRange(1, 9));
  write_nrrd(p.string(), pattern_volume(type, dims), *rc::gen::arbitrary<bool>());
  std::string bytes = read_text(p);
  const auto edits = *rc::gen::container<std::vector<std::pair<std::size_t, char>>>(
      *rc::gen::inRange<std::size_t>(0, 4),
      rc::gen::pair(rc::gen::oneOf(rc::gen::inRange<std::size_t>(0, bytes.size()),  // header-heavy
                                   rc::gen::inRange<std::size_t>(0, std::min<std::size_t>(bytes.size(), 220))),
                    rc::gen::arbitrary<char>()));
  for (const auto& [at, c] : edits) bytes[at] = c;
  if (*rc::gen::arbitrary<bool>()) bytes.resize(*rc::gen::inRange<std::size_t>(0, bytes.size()));
  write_text(p, bytes);
  try {
    const Volume v = read_nrrd(p.string());
    RC_ASSERT(v.desc().byte_size() > 0u);
  } catch (const InputError& e) {
    RC_ASSERT(std::string(e.what()).find(p.string()) != std::string::npos);
  }
}

// ---- writing failures ----------------------------------------------------------------------------

TEST(NrrdWrite, UnwritablePathThrowsAndLeavesNoFile) {
  const fs::path dir = scratch_dir();
  const Volume v = pattern_volume(VoxelType::U8);
  const std::string no_dir = (dir / "missing" / "v.nrrd").string();
  expect_input_error([&] { write_nrrd(no_dir, v); }, no_dir, "cannot write");
  write_text(dir / "file", "x");
  const std::string under_file = (dir / "file" / "v.nhdr").string();
  expect_input_error([&] { write_nrrd(under_file, v, true); }, under_file, "cannot write");
  // The destination is a directory: payload written, then the final rename fails; nothing stays.
  fs::create_directories(dir / "taken.nrrd" / "inner");
  const std::string taken = (dir / "taken.nrrd").string();
  expect_input_error([&] { write_nrrd(taken, v); }, taken, "cannot write");
  fs::create_directories(dir / "taken2.nhdr" / "inner");
  const std::string taken2 = (dir / "taken2.nhdr").string();
  expect_input_error([&] { write_nrrd(taken2, v); }, taken2, "cannot write");
  // taken2.raw was renamed into place before the header's rename failed, and is removed again.
  EXPECT_EQ(listing(dir), (std::set<std::string>{"file", "taken.nrrd", "taken2.nhdr"}));

  if (::geteuid() != 0) {  // root ignores permissions
    fs::create_directories(dir / "ro");
    fs::permissions(dir / "ro", fs::perms::owner_read | fs::perms::owner_exec);
    const std::string ro = (dir / "ro" / "v.nrrd").string();
    expect_input_error([&] { write_nrrd(ro, v); }, ro, "Permission denied");
    EXPECT_TRUE(listing(dir / "ro").empty());
    fs::permissions(dir / "ro", fs::perms::owner_all);
  }
}

TEST(NrrdWrite, RejectsOtherExtensions) {
  const fs::path dir = scratch_dir();
  const std::string p = (dir / "v.raw").string();
  expect_input_error([&] { write_nrrd(p, pattern_volume(VoxelType::U8)); }, p, "must end in .nrrd");
  EXPECT_TRUE(listing(dir).empty());
}

}  // namespace
}  // namespace sl
