// Zarr v3 / OME-Zarr 0.5 interoperability with the reference implementation, zarr-python 3: stores it
// writes with every supported codec combination (sharded and not, shard index at the start or end,
// with and without crc32c, partially empty and missing shards, both chunk key encodings, big-endian
// bytes, transpose, int16) read voxel for voxel through ZarrVolumeSource and the in-core path; and
// corrupted shards are errors naming the store, the level and the shard. Stores `ingest --format
// zarr3` writes (sharded and not) opened by zarr-python 3 and compared voxel for voxel with
// MemoryVolumeSource's pyramid, and read back by our reader.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <ostream>

#include "cache/formats/ingest.h"
#include "cache/formats/nrrd/nrrd.h"
#include "cache/formats/zarr/source.h"
#include "core/util/error.h"
#include "tests/cache/formats/zarr_bricks_match.h"
#include "tests/cache/formats/zarr_test_util.h"
#include "tests/test_util.h"

namespace sl {
namespace {

namespace fs = std::filesystem;

struct Peer3Case {
  std::string name, dtype;
  VoxelType type;
  std::string args;  // zarr3_tool.py make flags
  bool labels = false;
  bool bare = false;  // a bare array: one level, unit spacing
};

std::ostream& operator<<(std::ostream& os, const Peer3Case& c) { return os << c.name; }

class Zarr3PeerRead : public ::testing::TestWithParam<Peer3Case> {};

TEST_P(Zarr3PeerRead, VoxelForVoxel) {
  SL_REQUIRE_PEER3();
  const Peer3Case& c = GetParam();
  const fs::path dir = test::scratch_dir();
  const fs::path store = dir / "peer.zarr", expected = dir / "expected";
  std::string out;
  const std::string args = "make " + store.string() + " " + expected.string() + " --dtype " + c.dtype +
                           " --shape 20,30,40 " + c.args + (c.labels ? " --labels" : "") + (c.bare ? " --bare" : "");
  ASSERT_EQ(test::run_peer3(args, &out), 0) << out;
  ZarrVolumeSource src(store.string());
  const int levels = c.bare ? 1 : 3;
  EXPECT_EQ(src.desc().dims, ivec3(40, 30, 20));
  EXPECT_EQ(src.desc().type, c.type);
  EXPECT_EQ(src.desc().spacing, c.bare ? vec3(1.0f) : vec3(0.25f, 0.25f, 0.5f));
  EXPECT_EQ(src.stored_levels(), levels);
  EXPECT_EQ(src.has_labels(), c.labels);
  for (int brick : {8, 16}) {
    SCOPED_TRACE("brick " + std::to_string(brick));
    test::expect_bricks_match(src, expected, levels, brick, false);
    if (c.labels) test::expect_bricks_match(src, expected, levels, brick, true);
  }
  const Volume v = read_zarr_volume(store.string());
  const auto b = test::read_bytes(expected.string() + ".0");
  ASSERT_EQ(b.size(), v.desc().byte_size());
  EXPECT_EQ(std::memcmp(v.data(), b.data(), b.size()), 0);
}

INSTANTIATE_TEST_SUITE_P(
    Codecs, Zarr3PeerRead,
    ::testing::Values(
        Peer3Case{"bytes_u8", "uint8", VoxelType::U8, "--chunks 8,8,8"},
        Peer3Case{"gzip_big_endian_u16_v2_keys", "uint16", VoxelType::U16,
                  "--chunks 5,7,9 --compressor gzip --endian big --keys v2 --sep ."},
        Peer3Case{"zstd_transpose_f32_dot_keys", "float32", VoxelType::F32,
                  "--chunks 4,16,16 --compressor zstd --transpose --sep ."},
        // Not an involution: decoding with the order instead of its inverse would be caught.
        Peer3Case{"gzip_transpose_1_2_0_u16", "uint16", VoxelType::U16,
                  "--chunks 4,6,10 --compressor gzip --transpose --order 1,2,0"},
        Peer3Case{"shard_transpose_2_0_1_u8", "uint8", VoxelType::U8,
                  "--chunks 4,6,10 --shards 8,12,20 --transpose --order 2,0,1 --holes"},
        Peer3Case{"blosc_bitshuffle_crc32c_u32", "uint32", VoxelType::U32,
                  "--chunks 8,16,32 --compressor blosc-lz4-bitshuffle --crc"},
        Peer3Case{"blosc_zstd_int16_as_float_missing", "int16", VoxelType::F32,
                  "--chunks 8,8,8 --compressor blosc-zstd --missing --fill -5"},
        Peer3Case{"shard_index_end_crc32c_holes_labels", "uint16", VoxelType::U16,
                  "--chunks 4,8,8 --shards 8,16,16 --compressor blosc-zstd --crc --holes --fill 300", true},
        Peer3Case{"shard_index_start_no_index_crc", "uint8", VoxelType::U8,
                  "--chunks 4,4,4 --shards 8,8,8 --index start --no-index-crc --compressor gzip --holes --fill 7"},
        Peer3Case{"shard_transpose_big_endian_v2_keys_missing", "uint16", VoxelType::U16,
                  "--chunks 5,5,5 --shards 10,10,10 --transpose --endian big --keys v2 --sep . --compressor zstd "
                  "--missing --holes"},
        Peer3Case{"shard_f32_nan_fill_missing", "float32", VoxelType::F32,
                  "--chunks 4,8,8 --shards 8,16,16 --index start --fill NaN --holes --missing --compressor blosc-lz4"},
        Peer3Case{"shard_5d_bare_array", "uint16", VoxelType::U16,
                  "--chunks 4,8,8 --shards 8,16,24 --ndim 5 --compressor zstd --holes", false, true}),
    [](const ::testing::TestParamInfo<Peer3Case>& i) { return i.param.name; });

// A sharded store written by the peer; returns the path of level 0's first shard.
fs::path sharded_store(const fs::path& dir, const std::string& extra) {
  std::string out;
  const std::string args = "make " + (dir / "s.zarr").string() + " " + (dir / "exp").string() +
                           " --dtype uint8 --shape 16,16,16 --chunks 4,4,4 --shards 8,8,8 --levels 1 " + extra;
  EXPECT_EQ(test::run_peer3(args, &out), 0) << out;
  return dir / "s.zarr" / "0" / "c" / "0" / "0" / "0";
}

void flip_byte(const fs::path& f, std::uint64_t offset_from_end) {
  std::fstream s(f, std::ios::in | std::ios::out | std::ios::binary);
  s.seekg(0, std::ios::end);
  const std::streamoff pos = std::streamoff(s.tellg()) - std::streamoff(offset_from_end);
  s.seekg(pos);
  char ch = 0;
  s.read(&ch, 1);
  ch = char(ch ^ 0x5a);
  s.seekp(pos);
  s.write(&ch, 1);
}

// Reads every brick; returns the message of the first error.
std::string read_all_error(const std::string& store) {
  try {
    const ZarrVolumeSource src(store);
    const BrickLayout layout = BrickLayout::make(src.desc(), 8);
    std::vector<std::byte> img(std::size_t(layout.stored_voxels()));
    for (int i = 0; i < layout.bricks(0).x * layout.bricks(0).y * layout.bricks(0).z; ++i) {
      const ivec3 nb = layout.bricks(0);
      src.read_brick(layout, BrickId::pack(0, ivec3(i % nb.x, (i / nb.x) % nb.y, i / (nb.x * nb.y))), img, {});
    }
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(Zarr3BadShard, IndexChecksumMismatchNamesStoreLevelAndShard) {
  SL_REQUIRE_PEER3();
  const fs::path dir = test::scratch_dir();
  const fs::path shard = sharded_store(dir, "--compressor zstd");
  flip_byte(shard, 6);  // inside the index (at the end), before its crc32c
  const std::string e = read_all_error((dir / "s.zarr").string());
  EXPECT_NE(e.find("s.zarr"), std::string::npos) << e;
  EXPECT_NE(e.find("level 0 (array '0') shard 'c/0/0/0'"), std::string::npos) << e;
  EXPECT_NE(e.find("shard index crc32c checksum mismatch"), std::string::npos) << e;
}

TEST(Zarr3BadShard, InnerChunkChecksumMismatch) {
  SL_REQUIRE_PEER3();
  const fs::path dir = test::scratch_dir();
  const fs::path shard = sharded_store(dir, "--crc --index end");
  // The first inner chunk starts the file (index at the end): corrupt its first byte.
  flip_byte(shard, fs::file_size(shard));
  const std::string e = read_all_error((dir / "s.zarr").string());
  EXPECT_NE(e.find("shard 'c/0/0/0' inner chunk (0,0,0): crc32c checksum mismatch"), std::string::npos) << e;
}

TEST(Zarr3BadShard, TruncatedShardAndOffsetsPastTheEnd) {
  SL_REQUIRE_PEER3();
  const fs::path dir = test::scratch_dir();
  const fs::path shard = sharded_store(dir, "--index start --no-index-crc");
  // Index at the start: 8 inner chunks x 16 bytes. Cutting the tail leaves entries pointing past the end.
  fs::resize_file(shard, 128 + 10);
  std::string e = read_all_error((dir / "s.zarr").string());
  EXPECT_NE(e.find("shard 'c/0/0/0' inner chunk"), std::string::npos) << e;
  EXPECT_NE(e.find("past the end of the 138-byte file"), std::string::npos) << e;
  fs::resize_file(shard, 100);
  e = read_all_error((dir / "s.zarr").string());
  EXPECT_NE(e.find("past the end of the 100-byte file"), std::string::npos) << e;
}

TEST(Zarr3BadShard, IndexEntryHalfEmpty) {
  SL_REQUIRE_PEER3();
  const fs::path dir = test::scratch_dir();
  const fs::path shard = sharded_store(dir, "--index start --no-index-crc");
  {
    std::fstream s(shard, std::ios::in | std::ios::out | std::ios::binary);
    const char ones[8] = {-1, -1, -1, -1, -1, -1, -1, -1};
    s.write(ones, 8);  // offset of inner chunk 0 = 2^64-1, nbytes left as is
  }
  const std::string e = read_all_error((dir / "s.zarr").string());
  EXPECT_NE(e.find("inner chunk (0,0,0): shard index entry (offset 18446744073709551615"), std::string::npos) << e;
}

struct Write3Case {
  std::string name, compressor;
  VoxelType type;
  int shard;
  bool labels;
};

std::ostream& operator<<(std::ostream& os, const Write3Case& c) { return os << c.name; }

class Zarr3PeerOpensOurs : public ::testing::TestWithParam<Write3Case> {};

TEST_P(Zarr3PeerOpensOurs, VoxelForVoxel) {
  SL_REQUIRE_PEER3();
  const Write3Case& c = GetParam();
  const fs::path dir = test::scratch_dir();
  const ivec3 dims(37, 22, 41);
  Volume v(VolumeDesc{dims, vec3(0.5f, 1.0f, 2.0f), c.type});
  auto labels = std::make_shared<Volume>(VolumeDesc{dims, vec3(1.0f), VoxelType::U16});
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x) {
        // Zero regions too, so inner chunks (and whole shards) are left empty and read as the fill value.
        const float f = float((x * 3 + y * 5 + z * 7) % 97);
        v.set(x, y, z, x < dims.x / 3 || z > 30 ? 0.0f : c.type == VoxelType::F32 ? f * 0.25f - 3.0f : f);
        labels->set(x, y, z, float((x / 5 + y / 7 + z / 3) % 9));
      }
  write_nrrd((dir / "in.nrrd").string(), v);
  if (c.labels) write_nrrd((dir / "lab.nrrd").string(), *labels);
  IngestOptions o;
  o.chunk = 8;
  o.compressor = zarr::compressor_from_name(c.compressor);
  o.zarr_format = 3;
  o.shard = c.shard;
  if (c.labels) o.labels = (dir / "lab.nrrd").string();
  const IngestResult r = ingest((dir / "in.nrrd").string(), (dir / "out.zarr").string(), o);
  EXPECT_EQ(r.levels, 4);

  std::string out;
  ASSERT_EQ(test::run_peer3("dump " + (dir / "out.zarr").string() + " " + (dir / "dump").string(), &out), 0) << out;
  EXPECT_NE(out.find("0 41x22x37"), std::string::npos) << out;
  const std::string shards = c.shard ? "shards=(" + std::to_string(8 * c.shard) + ", " : "shards=None";
  EXPECT_NE(out.find(shards), std::string::npos) << out;
  const MemoryVolumeSource ref(std::make_shared<const Volume>(v), c.labels ? labels : nullptr);
  for (int l = 0; l < r.levels; ++l) {
    const auto b = test::read_bytes(dir / ("dump." + std::to_string(l)));
    ASSERT_EQ(b.size(), ref.level(l).desc().byte_size()) << "level " << l;
    EXPECT_EQ(std::memcmp(b.data(), ref.level(l).data(), b.size()), 0) << "level " << l;
    if (c.labels) {
      const auto lb = test::read_bytes(dir / ("dump.labels." + std::to_string(l)));
      ASSERT_EQ(lb.size(), ref.label_level(l)->desc().byte_size()) << "labels level " << l;
      EXPECT_EQ(std::memcmp(lb.data(), ref.label_level(l)->data(), lb.size()), 0) << "labels level " << l;
    }
  }
  const ZarrVolumeSource src((dir / "out.zarr").string());
  EXPECT_EQ(src.max_label(), c.labels ? 8u : 0u);
  const BrickLayout layout = BrickLayout::make(v.desc(), 8);
  std::vector<std::byte> a(std::size_t(layout.stored_voxels()) * std::size_t(voxel_size(c.type))), b(a.size());
  std::vector<std::byte> la(c.labels ? std::size_t(layout.stored_voxels()) * 2 : 0), lb(la.size());
  for (int l = 0; l < layout.levels; ++l) {
    const ivec3 nb = layout.bricks(l);
    for (int i = 0; i < nb.x * nb.y * nb.z; ++i) {
      const BrickId id = BrickId::pack(l, ivec3(i % nb.x, (i / nb.x) % nb.y, i / (nb.x * nb.y)));
      src.read_brick(layout, id, a, la);
      ref.read_brick(layout, id, b, lb);
      ASSERT_EQ(a, b) << to_string(id);
      ASSERT_EQ(la, lb) << to_string(id);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Writer, Zarr3PeerOpensOurs,
                         ::testing::Values(Write3Case{"shard2_blosc_zstd_u16_labels", "blosc-zstd", VoxelType::U16, 2, true},
                                           Write3Case{"shard3_zstd_u8", "zstd", VoxelType::U8, 3, false},
                                           Write3Case{"unsharded_gzip_f32", "gzip", VoxelType::F32, 0, false},
                                           Write3Case{"shard2_none_u32_labels", "none", VoxelType::U32, 2, true},
                                           Write3Case{"unsharded_blosc_lz4_u8_labels", "blosc-lz4", VoxelType::U8, 0, true}),
                         [](const ::testing::TestParamInfo<Write3Case>& i) { return i.param.name; });

TEST(Zarr3Ingest, RefusesShardsOnV2AndZlibOnV3) {
  const fs::path dir = test::scratch_dir();
  write_nrrd((dir / "in.nrrd").string(), Volume(VolumeDesc{ivec3(8), vec3(1.0f), VoxelType::U8}));
  IngestOptions o;
  o.chunk = 8;
  o.shard = 2;
  EXPECT_THROW(ingest((dir / "in.nrrd").string(), (dir / "a.zarr").string(), o), InputError);
  o.zarr_format = 3;
  o.compressor = zarr::compressor_from_name("zlib");
  EXPECT_THROW(ingest((dir / "in.nrrd").string(), (dir / "b.zarr").string(), o), InputError);
  EXPECT_FALSE(fs::exists(dir / "a.zarr") || fs::exists(dir / "b.zarr"));
}

}  // namespace
}  // namespace sl
