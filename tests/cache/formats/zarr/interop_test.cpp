// OME-Zarr interoperability with a real peer, python3-zarr: stores it writes (every compressor,
// byte order and dtype, chunk shapes unlike the brick size, missing chunks, both dimension separators,
// 5-D arrays, label images) read voxel for voxel through ZarrVolumeSource; stores `ingest` writes
// opened by python3-zarr and compared voxel for voxel with MemoryVolumeSource's pyramid.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <ostream>

#include "cache/formats/ingest.h"
#include "cache/formats/nrrd/nrrd.h"
#include "cache/formats/zarr/source.h"
#include "cache/volume_source.h"
#include "tests/cache/formats/zarr_bricks_match.h"
#include "tests/cache/formats/zarr_test_util.h"
#include "tests/test_util.h"

namespace sl {
namespace {

namespace fs = std::filesystem;

struct PeerCase {
  std::string name, dtype, compressor, chunks, sep = ".";
  VoxelType type = VoxelType::U8;
  std::string extra;  // more zarr_tool.py make flags
  bool labels = false;
};

std::ostream& operator<<(std::ostream& os, const PeerCase& c) { return os << c.name; }

class ZarrPeerRead : public ::testing::TestWithParam<PeerCase> {};

TEST_P(ZarrPeerRead, VoxelForVoxel) {
  SL_REQUIRE_PYTHON("zarr, numcodecs");
  const PeerCase& c = GetParam();
  const fs::path dir = test::scratch_dir();
  const fs::path store = dir / "peer.zarr", expected = dir / "expected";
  std::string out;
  const std::string args = "make " + store.string() + " " + expected.string() + " --dtype '" + c.dtype +
                           "' --shape 20,30,40 --chunks " + c.chunks + " --compressor " + c.compressor +
                           " --sep " + c.sep + " --levels 3 " + (c.labels ? "--labels " : "") + c.extra;
  ASSERT_EQ(test::run_peer(args, &out), 0) << out;
  ZarrVolumeSource src(store.string());
  EXPECT_EQ(src.desc().dims, ivec3(40, 30, 20));
  EXPECT_EQ(src.desc().type, c.type);
  EXPECT_EQ(src.desc().spacing, vec3(0.25f, 0.25f, 0.5f));
  EXPECT_EQ(src.stored_levels(), 3);
  EXPECT_EQ(src.has_labels(), c.labels);
  for (int brick : {8, 16}) {
    SCOPED_TRACE("brick " + std::to_string(brick));
    test::expect_bricks_match(src, expected, 3, brick, false);
    if (c.labels) test::expect_bricks_match(src, expected, 3, brick, true);
  }
  // The in-core path reads the same level 0.
  const Volume v = read_zarr_volume(store.string());
  const auto b = test::read_bytes(expected.string() + ".0");
  ASSERT_EQ(b.size(), v.desc().byte_size());
  EXPECT_EQ(std::memcmp(v.data(), b.data(), b.size()), 0);
}

INSTANTIATE_TEST_SUITE_P(
    Compressors, ZarrPeerRead,
    ::testing::Values(PeerCase{"none_u8", "|u1", "none", "8,8,8", ".", VoxelType::U8, ""},
                      PeerCase{"zlib_u16_odd_chunks_slash", "<u2", "zlib", "5,7,9", "/", VoxelType::U16, ""},
                      PeerCase{"gzip_big_endian_u16", ">u2", "gzip", "16,16,16", ".", VoxelType::U16, ""},
                      PeerCase{"zstd_f32_flat_chunks", "<f4", "zstd", "1,30,40", "/", VoxelType::F32, ""},
                      PeerCase{"blosc_lz4_shuffle_u32", "<u4", "blosc-lz4-shuffle", "8,16,32", ".", VoxelType::U32, ""},
                      PeerCase{"blosc_zstd_bitshuffle_big_f32", ">f4", "blosc-zstd-bitshuffle", "7,7,7", "/",
                               VoxelType::F32, ""},
                      PeerCase{"blosc_zlib_noshuffle_missing_fill", "|u1", "blosc-zlib-noshuffle", "4,8,8", ".",
                               VoxelType::U8, "--missing --fill 7"},
                      PeerCase{"blosc_lz4hc_5d_labels", "<u2", "blosc-lz4hc", "8,8,8", "/", VoxelType::U16,
                               "--ndim 5", true},
                      PeerCase{"missing_chunks_fill_u16_big", ">u2", "zstd", "16,4,32", "/", VoxelType::U16,
                               "--missing --fill 300", true}),
    [](const ::testing::TestParamInfo<PeerCase>& i) { return i.param.name; });

// A volume of each type with a recognisable pattern (not all zero, so chunks are written).
Volume pattern(VoxelType t, ivec3 dims) {
  Volume v(VolumeDesc{dims, vec3(0.5f, 1.0f, 2.0f), t});
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x) {
        const float f = float((x * 3 + y * 5 + z * 7) % 97);
        // Zero regions too, so all-zero chunks are skipped and must read back as the fill value.
        v.set(x, y, z, x < dims.x / 3 ? 0.0f : t == VoxelType::F32 ? f * 0.25f - 3.0f : f * (t == VoxelType::U8 ? 1.0f : 613.0f));
      }
  return v;
}

struct WriteCase {
  std::string compressor;
  VoxelType type;
  bool labels;
  // gtest prints the parameter of a failing case; without this it dumps the struct's bytes.
  friend void PrintTo(const WriteCase& c, std::ostream* os) {
    *os << c.compressor << ' ' << to_string(c.type) << (c.labels ? " with labels" : "");
  }
};

class ZarrPeerOpensOurs : public ::testing::TestWithParam<WriteCase> {};

TEST_P(ZarrPeerOpensOurs, VoxelForVoxel) {
  SL_REQUIRE_PYTHON("zarr, numcodecs");
  const WriteCase& c = GetParam();
  const fs::path dir = test::scratch_dir();
  const ivec3 dims(37, 22, 41);
  const Volume v = pattern(c.type, dims);
  write_nrrd((dir / "in.nrrd").string(), v);
  auto labels = std::make_shared<Volume>(VolumeDesc{dims, vec3(1.0f), VoxelType::U16});
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x) labels->set(x, y, z, float((x / 5 + y / 7 + z / 3) % 9));
  if (c.labels) write_nrrd((dir / "lab.nrrd").string(), *labels);

  IngestOptions o;
  o.chunk = 8;
  o.compressor = zarr::compressor_from_name(c.compressor);
  if (c.labels) o.labels = (dir / "lab.nrrd").string();
  const IngestResult r = ingest((dir / "in.nrrd").string(), (dir / "out.zarr").string(), o);
  EXPECT_EQ(r.levels, ingest_levels(dims, 8));
  EXPECT_EQ(r.levels, 4);  // 41 -> 21 -> 11 -> 6 fits one chunk

  std::string out;
  ASSERT_EQ(test::run_peer("dump " + (dir / "out.zarr").string() + " " + (dir / "dump").string(), &out), 0) << out;
  EXPECT_NE(out.find("0 41x22x37"), std::string::npos) << out;
  EXPECT_NE(out.find("0.5"), std::string::npos) << out;  // x spacing in the scale transform
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
  // And our reader agrees with the reference at every level, including the derived ones.
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

INSTANTIATE_TEST_SUITE_P(Compressors, ZarrPeerOpensOurs,
                         ::testing::Values(WriteCase{"none", VoxelType::U8, true}, WriteCase{"zlib", VoxelType::U16, false},
                                           WriteCase{"gzip", VoxelType::U8, false}, WriteCase{"zstd", VoxelType::F32, true},
                                           WriteCase{"blosc-lz4", VoxelType::U32, false},
                                           WriteCase{"blosc-zstd", VoxelType::U16, true},
                                           WriteCase{"blosc-zlib", VoxelType::F32, false}),
                         [](const ::testing::TestParamInfo<WriteCase>& i) {
                           std::string n = i.param.compressor + "_" + to_string(i.param.type);
                           for (char& ch : n) ch = ch == '-' ? '_' : ch;
                           return n + (i.param.labels ? "_labels" : "");
                         });

}  // namespace
}  // namespace sl
