// Bad OME-Zarr input: every problem is an InputError naming the store and, where it applies, the
// level (array) and chunk; nothing crashes. Metadata problems surface when the store is opened, chunk
// problems when a brick needs the chunk (the out-of-core fault path then reports the brick).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "cache/formats/ingest.h"
#include "cache/formats/nrrd/nrrd.h"
#include "cache/formats/zarr/source.h"
#include "core/util/error.h"
#include "tests/cache/formats/zarr_test_util.h"
#include "tests/test_util.h"

namespace sl {
namespace {

namespace fs = std::filesystem;

class ZarrBadInput : public ::testing::Test {
 protected:
  // A 40x40x40 u8 store with chunk 16 (3 chunks per axis, several levels), written by ingest.
  void make(const std::string& compressor) {
    dir = test::scratch_dir();
    Volume v(VolumeDesc{ivec3(40), vec3(1.0f), VoxelType::U8});
    for (int z = 0; z < 40; ++z)
      for (int y = 0; y < 40; ++y)
        for (int x = 0; x < 40; ++x) v.set(x, y, z, float((x + 2 * y + 3 * z) % 250 + 1));
    write_nrrd((dir / "v.nrrd").string(), v);
    IngestOptions o;
    o.chunk = 16;
    o.compressor = zarr::compressor_from_name(compressor);
    ingest((dir / "v.nrrd").string(), store().string(), o);
  }
  fs::path store() const { return dir / "s.zarr"; }
  fs::path chunk(int level, const std::string& key) const { return store() / std::to_string(level) / key; }

  // Reading every brick of `level` must throw an InputError whose message holds every needle.
  void expect_brick_error(int level, std::vector<std::string> needles) {
    const ZarrVolumeSource src(store().string());
    const BrickLayout layout = BrickLayout::make(src.desc(), 16);
    std::vector<std::byte> out(layout.stored_voxels());
    needles.push_back(store().string());
    bool threw = false;
    const ivec3 nb = layout.bricks(level);
    for (int i = 0; i < nb.x * nb.y * nb.z && !threw; ++i) {
      try {
        src.read_brick(layout, BrickId::pack(level, ivec3(i % nb.x, (i / nb.x) % nb.y, i / (nb.x * nb.y))), out, {});
      } catch (const InputError& e) {
        threw = true;
        for (const std::string& n : needles) EXPECT_NE(std::string(e.what()).find(n), std::string::npos) << n << " in " << e.what();
      }
    }
    EXPECT_TRUE(threw);
  }
  // Opening the store must throw an InputError holding every needle.
  void expect_open_error(std::vector<std::string> needles) {
    needles.push_back(store().string());
    try {
      ZarrVolumeSource src(store().string());
      ADD_FAILURE() << "expected InputError";
    } catch (const InputError& e) {
      for (const std::string& n : needles) EXPECT_NE(std::string(e.what()).find(n), std::string::npos) << n << " in " << e.what();
    }
  }
  void edit(const fs::path& p, const std::string& from, const std::string& to) {
    std::string s = test::read_text(p);
    const auto at = s.find(from);
    ASSERT_NE(at, std::string::npos) << from << " in " << p;
    s.replace(at, from.size(), to);
    test::write_text(p, s);
  }
  fs::path dir;
};

TEST_F(ZarrBadInput, TruncatedChunk) {
  for (const std::string c : {"zstd", "zlib", "gzip", "blosc-lz4", "blosc-zstd"}) {
    SCOPED_TRACE(c);
    make(c);
    fs::resize_file(chunk(0, "1/1/1"), fs::file_size(chunk(0, "1/1/1")) / 2);
    expect_brick_error(0, {"level 0", "chunk '1/1/1'"});
  }
}

TEST_F(ZarrBadInput, CorruptChunk) {
  for (const std::string c : {"zstd", "zlib", "blosc-lz4"}) {
    SCOPED_TRACE(c);
    make(c);
    test::write_text(chunk(0, "0/2/1"), std::string(100, '\x5a'));
    expect_brick_error(0, {"level 0", "chunk '0/2/1'", "corrupt"});
  }
}

TEST_F(ZarrBadInput, ChunkOfTheWrongSizeAfterDecompression) {
  for (const std::string c : {"none", "zstd", "zlib", "blosc-zstd"}) {
    SCOPED_TRACE(c);
    make(c);
    const std::vector<std::byte> small(16 * 16 * 15, std::byte{1});
    const std::vector<std::byte> enc = zarr::encode(zarr::compressor_from_name(c), small, 1);
    std::ofstream(chunk(1, "0/0/0"), std::ios::binary).write(reinterpret_cast<const char*>(enc.data()), std::streamsize(enc.size()));
    expect_brick_error(1, {"level 1", "chunk '0/0/0'", "expected 4096 bytes"});
  }
}

TEST_F(ZarrBadInput, UnknownCompressorAndDtypeAndOrder) {
  make("zstd");
  edit(store() / "1" / ".zarray", "\"zstd\"", "\"lzma\"");
  expect_open_error({"level 1", "array '1'", "unknown compressor id 'lzma'"});
  make("zstd");
  edit(store() / "0" / ".zarray", "\"|u1\"", "\"<i8\"");
  expect_open_error({"level 0", "unsupported dtype '<i8'"});
  make("zstd");
  edit(store() / "0" / ".zarray", "\"C\"", "\"F\"");
  expect_open_error({"level 0", "order 'F'"});
  make("none");
  edit(store() / "0" / ".zarray", "\"filters\": null", "\"filters\": [{\"id\": \"delta\"}]");
  expect_open_error({"level 0", "filters"});
}

TEST_F(ZarrBadInput, InconsistentLevels) {
  make("zstd");
  edit(store() / "1" / ".zarray", "20,\n    20,\n    20", "20,\n    20,\n    13");
  expect_open_error({"level 1", "not a 2x reduction"});
  make("zstd");
  edit(store() / "2" / ".zarray", "\"|u1\"", "\"<u2\"");
  expect_open_error({"level 2", "dtype"});
  make("zstd");
  edit(store() / ".zattrs", "2.0,\n", "3.0,\n");  // level 1's z scale: 3x level 0's
  expect_open_error({"level 1", "scale"});
}

TEST_F(ZarrBadInput, MissingZarrayAndMalformedJson) {
  make("zstd");
  fs::remove(store() / "1" / ".zarray");
  expect_open_error({"level 1", "missing .zarray"});
  make("zstd");
  test::write_text(store() / "0" / ".zarray", "{\"zarr_format\": 2, \"shape\": [40, 40");
  expect_open_error({"level 0", "malformed JSON", ".zarray"});
  make("zstd");
  test::write_text(store() / ".zattrs", "{\"multiscales\": [");
  expect_open_error({"malformed JSON", ".zattrs"});
  make("zstd");
  edit(store() / ".zattrs", "\"z\"", "\"q\"");
  expect_open_error({"axes"});
  make("zstd");
  fs::remove_all(store() / "0");
  fs::remove(store() / ".zattrs");
  expect_open_error({"not an image store"});
}

TEST_F(ZarrBadInput, AbsurdAndOverflowingShapes) {
  make("zstd");
  edit(store() / "0" / ".zarray", "40,\n    40,\n    40", "2000000000,\n    2000000000,\n    2000000000");
  expect_open_error({"level"});
  make("zstd");
  edit(store() / "0" / ".zarray", "40,\n    40,\n    40", "40,\n    -40,\n    40");
  expect_open_error({"level 0", "out of range"});
  make("zstd");
  edit(store() / "0" / ".zarray", "40,\n    40,\n    40", "40,\n    40,\n    99999999999");
  expect_open_error({"level 0", "out of range"});
  make("zstd");
  edit(store() / "0" / ".zarray", "\"chunks\": [\n    16,\n    16,\n    16", "\"chunks\": [\n    4096,\n    4096,\n    4096");
  expect_open_error({"level 0", "1 GiB"});
  // A non-singleton channel axis.
  make("zstd");
  edit(store() / "0" / ".zarray", "\"shape\": [", "\"shape\": [3, ");
  edit(store() / "0" / ".zarray", "\"chunks\": [", "\"chunks\": [1, ");
  expect_open_error({"level 0", "size 3"});
}

TEST_F(ZarrBadInput, PeerStoreWithWrongSizeChunk) {
  SL_REQUIRE_PYTHON("zarr, numcodecs");
  dir = test::scratch_dir();
  std::string out;
  ASSERT_EQ(test::run_peer("make " + store().string() + " " + (dir / "e").string() +
                               " --shape 20,20,20 --chunks 8,8,8 --compressor blosc-zstd --levels 2", &out), 0) << out;
  // Replace a chunk with a valid blosc buffer of the wrong size, made by numcodecs itself.
  const std::string py = std::string(test::kPeerPython) +
                         " -c 'import numcodecs, numpy; open(\"" + (store() / "0" / "1.1.1").string() +
                         "\", \"wb\").write(numcodecs.Blosc(cname=\"zstd\").encode(numpy.zeros(100, \"u1\")))'";
  ASSERT_EQ(std::system(py.c_str()), 0);
  expect_brick_error(0, {"level 0", "chunk '1.1.1'", "blosc chunk decompresses to 100 bytes, expected 512 bytes"});
}

}  // namespace
}  // namespace sl
