// Zarr v3 arrays tensorstore (a second reference implementation, after zarr-python 3 in
// v3_interop_test.cpp) writes — sharded with the index at the start and at the end, inner chunks
// raw, gzip, zstd, blosc, with and without crc32c, odd shapes, an unwritten shard — read voxel for voxel
// by ZarrVolumeSource and the in-core read.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <ostream>

#include "cache/formats/zarr/source.h"
#include "tests/cache/formats/tensorstore_peer.h"
#include "tests/cache/formats/zarr_bricks_match.h"

namespace sl {
namespace {

namespace fs = std::filesystem;

struct Zarr3Case {
  std::string name, dtype;
  VoxelType type;
  std::string args;  // tensorstore_tool.py zarr3 flags
};

std::ostream& operator<<(std::ostream& os, const Zarr3Case& c) { return os << c.name; }

class TensorstoreZarr3Read : public ::testing::TestWithParam<Zarr3Case> {};

TEST_P(TensorstoreZarr3Read, VoxelForVoxel) {
  SL_REQUIRE_TENSORSTORE();
  const Zarr3Case& c = GetParam();
  const fs::path dir = test::scratch_dir();
  const fs::path store = dir / "ts.zarr", expected = dir / "expected";
  std::string out;
  ASSERT_EQ(test::run_tensorstore("zarr3 " + store.string() + " " + expected.string() + " --dtype " + c.dtype +
                                      " --shape 21,29,37 " + c.args,
                                  &out),
            0)
      << out;
  ZarrVolumeSource src(store.string());
  EXPECT_EQ(src.desc().dims, ivec3(37, 29, 21));
  EXPECT_EQ(src.desc().type, c.type);
  EXPECT_EQ(src.stored_levels(), 1);
  for (int brick : {8, 16}) {
    SCOPED_TRACE("brick " + std::to_string(brick));
    test::expect_bricks_match(src, expected, 1, brick, false);
  }
  const Volume v = read_zarr_volume(store.string());
  const auto b = test::read_bytes(expected.string() + ".0");
  ASSERT_EQ(b.size(), v.desc().byte_size());
  EXPECT_EQ(std::memcmp(v.data(), b.data(), b.size()), 0);
}

INSTANTIATE_TEST_SUITE_P(
    Tensorstore, TensorstoreZarr3Read,
    ::testing::Values(Zarr3Case{"unsharded_raw_u8", "uint8", VoxelType::U8, "--chunks 8,8,8"},
                      Zarr3Case{"unsharded_gzip_crc_f32", "float32", VoxelType::F32, "--chunks 5,7,9 --compressor gzip --crc"},
                      Zarr3Case{"shard_end_raw_u16", "uint16", VoxelType::U16, "--chunks 4,4,4 --shards 8,8,8 --index end"},
                      Zarr3Case{"shard_start_zstd_u16_holes", "uint16", VoxelType::U16,
                                "--chunks 4,8,8 --shards 8,16,16 --index start --compressor zstd --holes"},
                      Zarr3Case{"shard_end_blosc_crc_u32", "uint32", VoxelType::U32,
                                "--chunks 8,8,8 --shards 16,16,16 --compressor blosc --crc --holes"},
                      Zarr3Case{"shard_start_gzip_u8", "uint8", VoxelType::U8,
                                "--chunks 3,5,7 --shards 6,10,14 --index start --compressor gzip"}),
    [](const ::testing::TestParamInfo<Zarr3Case>& i) { return i.param.name; });

}  // namespace
}  // namespace sl
