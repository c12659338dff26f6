// Neuroglancer precomputed interoperability with the reference implementation, tensorstore: volumes it
// writes — raw (and gzip-wrapped) images of u8, u16, f32, sharded and unsharded (identity and
// murmurhash3_x86_128 hashes, raw and gzip minishard indices and data, several preshift/minishard/shard
// bit choices), compressed_segmentation labels of uint32 and uint64, raw uint32/uint64 labels, odd shapes,
// voxel offsets, missing chunks, several scales — read voxel for voxel through PrecomputedVolumeSource
// (every brick of every level, derived levels included) and the in-core read; and a render of a
// tensorstore-written volume with labels equal to the render of the same data from NRRD, in core and
// out of core, and from the tests' own HTTP server (precomputed://http://…) as from the directory.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <ostream>

#include "cache/formats/nrrd/nrrd.h"
#include "cache/formats/precomputed/source.h"
#include "cache/stores/counting_byte_store.h"
#include "core/util/image.h"
#include "tests/cache/formats/tensorstore_peer.h"
#include "tests/cache/formats/zarr_bricks_match.h"
#include "tests/http_test_server.h"

namespace sl {
namespace {

namespace fs = std::filesystem;

struct PeerCase {
  std::string name, dtype;
  VoxelType type;
  std::string args;  // tensorstore_tool.py make flags
  bool labels = false;
  int scales = 3;
};

std::ostream& operator<<(std::ostream& os, const PeerCase& c) { return os << c.name; }

class PrecomputedPeerRead : public ::testing::TestWithParam<PeerCase> {};

TEST_P(PrecomputedPeerRead, VoxelForVoxel) {
  SL_REQUIRE_TENSORSTORE();
  const PeerCase& c = GetParam();
  const fs::path dir = test::scratch_dir();
  const fs::path vol = dir / "vol", expected = dir / "expected";
  std::string out;
  const std::string args = "make " + vol.string() + " " + expected.string() + " --dtype " + c.dtype +
                           " --shape 37,29,21 --scales " + std::to_string(c.scales) + " " + c.args +
                           (c.labels ? " --labels" : "");
  ASSERT_EQ(test::run_tensorstore(args, &out), 0) << out;
  // Labels: the volume is its own label volume, so both the intensity and label paths are checked.
  const std::shared_ptr<PrecomputedVolumeSource> src = open_precomputed(vol.string(), c.labels ? vol.string() : "");
  EXPECT_EQ(src->desc().dims, ivec3(37, 29, 21));
  EXPECT_EQ(src->desc().type, c.type);
  EXPECT_EQ(src->desc().spacing, vec3(4.0f, 4.0f, 8.0f));
  EXPECT_EQ(src->stored_levels(), c.scales);
  EXPECT_EQ(src->has_labels(), c.labels);
  if (c.labels) {
    for (int l = 0; l < c.scales; ++l) {
      fs::copy_file(expected.string() + "." + std::to_string(l), expected.string() + ".labels." + std::to_string(l));
    }
  }
  for (int brick : {8, 16}) {
    SCOPED_TRACE("brick " + std::to_string(brick));
    test::expect_bricks_match(*src, expected, c.scales, brick, false);
    if (c.labels) test::expect_bricks_match(*src, expected, c.scales, brick, true);
  }
  const Volume v = read_precomputed_volume(vol.string());
  const auto b = test::read_bytes(expected.string() + ".0");
  ASSERT_EQ(b.size(), v.desc().byte_size());
  EXPECT_EQ(std::memcmp(v.data(), b.data(), b.size()), 0);
  EXPECT_EQ(v.desc().spacing, vec3(4.0f, 4.0f, 8.0f));
}

const std::string kMurmur = "--sharding murmurhash3_x86_128 ";
const std::string kIdentity = "--sharding identity ";

INSTANTIATE_TEST_SUITE_P(
    Tensorstore, PrecomputedPeerRead,
    ::testing::Values(
        PeerCase{"raw_u8", "uint8", VoxelType::U8, "--chunks 8,8,8"},
        PeerCase{"raw_u16_offset_holes", "uint16", VoxelType::U16, "--chunks 16,8,4 --offset 3,-5,7 --holes"},
        PeerCase{"raw_f32_gzip_files", "float32", VoxelType::F32, "--chunks 8,16,8 --gzip-files --holes"},
        PeerCase{"raw_u16_one_scale", "uint16", VoxelType::U16, "--chunks 64,64,64", false, 1},
        PeerCase{"shard_identity_raw_raw_u16", "uint16", VoxelType::U16,
                 kIdentity + "--chunks 8,8,8 --minishard 2 --shard 1"},
        PeerCase{"shard_identity_gzip_data_u8", "uint8", VoxelType::U8,
                 kIdentity + "--chunks 8,8,8 --preshift 1 --minishard 1 --shard 2 --data gzip --holes"},
        PeerCase{"shard_murmur_gzip_index_u8", "uint8", VoxelType::U8,
                 kMurmur + "--chunks 8,4,8 --minishard 3 --shard 2 --minishard-index gzip"},
        PeerCase{"shard_murmur_gzip_gzip_f32_holes", "float32", VoxelType::F32,
                 kMurmur + "--chunks 8,8,8 --preshift 2 --minishard 1 --shard 3 --minishard-index gzip --data gzip --holes"},
        PeerCase{"shard_single_file_u16", "uint16", VoxelType::U16, kMurmur + "--chunks 16,16,8 --minishard 0 --shard 0"},
        PeerCase{"cseg_u32", "uint32", VoxelType::U32, "--chunks 16,16,8 --encoding compressed_segmentation", true},
        PeerCase{"cseg_u64_small_blocks_holes", "uint64", VoxelType::U32,
                 "--chunks 8,8,8 --encoding compressed_segmentation --block 4,4,2 --big-ids --holes --offset 1,2,3", true},
        PeerCase{"cseg_u64_sharded", "uint64", VoxelType::U32,
                 kMurmur + "--chunks 8,8,8 --encoding compressed_segmentation --block 8,4,2 --minishard 2 --shard 1 "
                           "--minishard-index gzip --data gzip",
                 true},
        PeerCase{"cseg_u32_sharded_identity", "uint32", VoxelType::U32,
                 kIdentity + "--chunks 16,8,8 --encoding compressed_segmentation --minishard 1 --shard 1 --holes", true},
        PeerCase{"raw_u64_labels", "uint64", VoxelType::U32, "--chunks 8,8,8 --big-ids", true},
        PeerCase{"raw_u32_labels_sharded", "uint32", VoxelType::U32, kIdentity + "--chunks 8,8,8 --minishard 1 --shard 1",
                 true}),
    [](const ::testing::TestParamInfo<PeerCase>& i) { return i.param.name; });

// A sharded read fetches index entries, minishard indices and chunks by range: far fewer bytes than the
// shard files when one brick is asked for.
TEST(PrecomputedPeer, OneBrickReadsOnlyItsChunks) {
  SL_REQUIRE_TENSORSTORE();
  const fs::path dir = test::scratch_dir();
  std::string out;
  ASSERT_EQ(test::run_tensorstore("make " + (dir / "v").string() + " " + (dir / "e").string() +
                                      " --dtype uint16 --shape 128,128,64 --chunks 16,16,16 " + kMurmur +
                                      "--minishard 2 --shard 0 --data gzip",
                                  &out),
            0)
      << out;
  const std::uint64_t shard_bytes = fs::file_size(dir / "v" / "s0" / "0.shard");
  auto bytes = std::make_shared<CountingByteStore>(std::make_shared<LocalByteStore>((dir / "v").string()));
  const precomputed::VolumeReader r(bytes, "v", std::make_shared<zarr::ChunkCache>(0));
  const std::uint64_t before = bytes->bytes();
  std::vector<std::byte> box(16 * 16 * 16 * 2);
  r.read_box(0, ivec3(32, 48, 16), ivec3(16), box.data());
  const std::uint64_t read = bytes->bytes() - before;
  EXPECT_EQ(bytes->requests(), 1u + 3u);  // info, then index entry, minishard index, chunk
  EXPECT_LT(read * 20, shard_bytes) << read << " of " << shard_bytes;
  const auto e = test::read_bytes((dir / "e.0").string());
  for (int z = 0; z < 16; ++z)
    for (int y = 0; y < 16; ++y)
      ASSERT_EQ(std::memcmp(box.data() + (std::size_t(z) * 16 + std::size_t(y)) * 32,
                            e.data() + ((std::size_t(16 + z) * 128 + std::size_t(48 + y)) * 128 + 32) * 2, 32), 0);
}

// One render of a tensorstore-written volume with compressed_segmentation labels equals the render of
// the same voxels from NRRD, in core and out of core (a single scale, so every coarser level is derived
// by the same reductions MemoryVolumeSource makes).
TEST(PrecomputedPeer, RenderEqualsTheNrrdRender) {
  SL_REQUIRE_TENSORSTORE();
  const fs::path dir = test::scratch_dir();
  const auto p = [&](const char* n) { return (dir / n).string(); };
  std::string out;
  ASSERT_EQ(test::run_tensorstore("make " + p("img") + " " + p("img_e") + " --dtype uint8 --shape 40,36,30 --chunks 16,16,8 " +
                                      kMurmur + "--minishard 1 --shard 1 --data gzip",
                                  &out),
            0)
      << out;
  ASSERT_EQ(test::run_tensorstore("make " + p("lab") + " " + p("lab_e") +
                                      " --dtype uint64 --labels --shape 40,36,30 --chunks 8,8,8 --encoding compressed_segmentation",
                                  &out),
            0)
      << out;
  const auto to_nrrd = [&](const std::string& raw, VoxelType t, const std::string& nrrd) {
    Volume v(VolumeDesc{ivec3(40, 36, 30), vec3(4.0f, 4.0f, 8.0f), t});
    const auto b = test::read_bytes(raw);
    ASSERT_EQ(b.size(), v.desc().byte_size());
    std::memcpy(v.data(), b.data(), b.size());
    write_nrrd(nrrd, v);
  };
  to_nrrd(p("img_e.0"), VoxelType::U8, p("img.nrrd"));
  to_nrrd(p("lab_e.0"), VoxelType::U32, p("lab.nrrd"));
  test::HttpTestServer server(dir);
  for (const std::string& mode : {std::string("dvr"), std::string("labels --enable all")}) {
    SCOPED_TRACE(mode);
    for (const std::string& ooc : {std::string(""), std::string(" --cache-mb 16 --brick 16 --frames 30")}) {
      SCOPED_TRACE(ooc.empty() ? "in core" : "out of core");
      const std::string args = "render --backend cpu --size 48x40 --mode " + mode + ooc;
      auto r = test::run_sparseleap(args + " --volume precomputed://" + p("img") + " --labels " + p("lab") + " --out " + p("pc"));
      ASSERT_EQ(r.exit_code, 0) << r.output;
      r = test::run_sparseleap(args + " --volume " + p("img.nrrd") + " --labels " + p("lab.nrrd") + " --out " + p("nr"));
      ASSERT_EQ(r.exit_code, 0) << r.output;
      EXPECT_EQ(read_exr(p("pc") + ".exr").rgba, read_exr(p("nr") + ".exr").rgba);
      // Over HTTP: the prefixed URL, labels recognised by their info file.
      r = test::run_sparseleap(args + " --volume precomputed://" + server.url("img") + " --labels " + server.url("lab") +
                               " --out " + p("http"));
      ASSERT_EQ(r.exit_code, 0) << r.output;
      EXPECT_EQ(read_exr(p("http") + ".exr").rgba, read_exr(p("nr") + ".exr").rgba);
    }
  }
}

}  // namespace
}  // namespace sl
