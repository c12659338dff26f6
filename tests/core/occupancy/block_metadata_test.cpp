// Culling blocks and their metadata (DESIGN.md "Data model"): the one-voxel dilation, clipping, validation, and
// the same answer from a brick with its apron (out of core) as from the whole volume (in core).
#include "core/occupancy/block_metadata.h"

#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include <cmath>
#include <cstring>
#include <set>
#include <vector>
#include <limits>

#include "core/occupancy/culling.h"
#include "core/util/error.h"
#include "core/frame/in_core_renderer.h"

namespace sl {
namespace {

TEST(BlockGrid, SizesAndClippedBoxes) {
  const BlockGrid g = make_block_grid(ivec3(97, 131, 73), vec3(0.5f, 1.0f, 2.0f), 16);
  EXPECT_EQ(g.blocks, ivec3(7, 9, 5));
  EXPECT_EQ(g.block_count(), 315u);
  const Box3 first = g.block_box(ivec3(0));
  EXPECT_EQ(first.lo, vec3(0.0f));
  EXPECT_EQ(first.hi, vec3(8.0f, 16.0f, 32.0f));
  const Box3 last = g.block_box(ivec3(6, 8, 4));
  EXPECT_EQ(last.lo, vec3(48.0f, 128.0f, 128.0f));
  EXPECT_EQ(last.hi, vec3(48.5f, 131.0f, 146.0f));  // clipped to the volume
  EXPECT_EQ(g.volume_box().hi, vec3(48.5f, 131.0f, 146.0f));
  for (std::size_t i = 0; i < g.block_count(); ++i) EXPECT_EQ(g.block_index(g.block_coord(i)), i);
}

TEST(BlockGrid, BlockSizeIsValidated) {
  for (int b : {4, 8, 16, 32}) EXPECT_NO_THROW(make_block_grid(ivec3(10), vec3(1.0f), b));
  for (int b : {0, 2, 12, 64, -16}) {
    try {
      make_block_grid(ivec3(10), vec3(1.0f), b);
      FAIL() << "block " << b << " accepted";
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), "--block");
    }
  }
}

// 8^3 volume, blocks of 4 (2^3 blocks): values placed to show the one-voxel dilation.
struct SmallVolume {
  Volume intensity, labels;
  SmallVolume() {
    VolumeDesc d;
    d.dims = ivec3(8);
    intensity = Volume(d);
    d.type = VoxelType::U16;
    labels = Volume(d);
    for (int z = 0; z < 8; ++z)
      for (int y = 0; y < 8; ++y)
        for (int x = 0; x < 8; ++x) {
          intensity.set(x, y, z, 10.0f);
          labels.set(x, y, z, 0.0f);
        }
    intensity.set(2, 2, 2, 77.0f);   // inside block 0 only (block 1's dilation starts at voxel 3)
    intensity.set(3, 3, 3, 50.0f);   // block 0's edge voxel: also in block (1,1,1)'s dilation
    intensity.set(4, 0, 0, 5.0f);    // block (1,0,0)'s edge voxel: also in block 0's dilation
    labels.set(1, 1, 1, 7.0f);
    labels.set(4, 4, 4, 9.0f);       // in block (1,1,1); dilated into block 0
    labels.set(7, 7, 7, 300.0f);
  }
};

TEST(BlockMetadata, MinMaxAndLabelsCoverTheBlockDilatedByOneVoxel) {
  const SmallVolume v;
  const BlockGrid g = make_block_grid(ivec3(8), vec3(1.0f), 4);
  const VolumeView lv = v.labels.view();
  const BlockMetadata b0 = compute_block_metadata(g, v.intensity.view(), &lv, 0, 0, 0);
  EXPECT_TRUE(b0.computed);
  EXPECT_EQ(b0.min, 5.0f);   // voxel (4,0,0) is one voxel outside block 0
  EXPECT_EQ(b0.max, 77.0f);
  EXPECT_EQ(b0.labels, (std::vector<std::uint32_t>{0, 7, 9}));
  const BlockMetadata b7 = compute_block_metadata(g, v.intensity.view(), &lv, 1, 1, 1);
  EXPECT_EQ(b7.min, 10.0f);
  EXPECT_EQ(b7.max, 50.0f);  // (3,3,3) is in the dilation, (2,2,2) is not
  EXPECT_EQ(b7.labels, (std::vector<std::uint32_t>{0, 9, 300}));
  const BlockMetadata b1 = compute_block_metadata(g, v.intensity.view(), nullptr, 1, 0, 0);
  EXPECT_FALSE(b1.has_labels);
  EXPECT_TRUE(b1.labels.empty());
  EXPECT_EQ(b1.min, 5.0f);
  EXPECT_EQ(b1.max, 50.0f);  // (3,3,3): x = 3 is block 1's dilation, y, z = 3 are inside
}

TEST(BlockMetadata, ParallelTableEqualsPerBlockAndIsCounted) {
  const SmallVolume v;
  const BlockGrid g = make_block_grid(ivec3(8), vec3(1.0f), 4);
  const VolumeView lv = v.labels.view();
  const std::uint64_t before = block_metadata_computations();
  const BlockMetadataTable t = compute_all_block_metadata(g, v.intensity.view(), &lv);
  EXPECT_EQ(block_metadata_computations() - before, 8u);
  for (std::size_t i = 0; i < g.block_count(); ++i) {
    const ivec3 b = g.block_coord(i);
    const BlockMetadata m = compute_block_metadata(g, v.intensity.view(), &lv, b.x, b.y, b.z);
    EXPECT_EQ(t.at(b).min, m.min);
    EXPECT_EQ(t.at(b).max, m.max);
    EXPECT_EQ(t.at(b).labels, m.labels);
  }
}

// Out of core, metadata comes from one brick with its one-voxel apron: for every culling block of
// every brick (bricks of 8, blocks of 4, odd dims so bricks and blocks are clipped), the same numbers
// as from the whole volume.
TEST(BlockMetadata, BrickWithApronGivesTheWholeVolumesAnswer) {
  VolumeDesc d;
  d.dims = ivec3(13, 11, 9);
  Volume intensity(d);
  d.type = VoxelType::U16;
  Volume labels(d);
  for (int z = 0; z < d.dims.z; ++z)
    for (int y = 0; y < d.dims.y; ++y)
      for (int x = 0; x < d.dims.x; ++x) {
        intensity.set(x, y, z, float((x * 37 + y * 11 + z * 5) % 97));
        labels.set(x, y, z, float((x / 3 + y / 4 + z) % 6));
      }
  const BlockGrid g = make_block_grid(d.dims, d.spacing, 4);
  const VolumeView lv = labels.view();
  constexpr int kBrick = 8, kStored = kBrick + 2;
  int checked = 0;
  for (int bz = 0; bz * kBrick < d.dims.z; ++bz)
    for (int by = 0; by * kBrick < d.dims.y; ++by)
      for (int bx = 0; bx * kBrick < d.dims.x; ++bx) {
        // The brick as the loader stores it: payload plus apron, clamped to the volume's edge voxels.
        const ivec3 first = ivec3(bx, by, bz) * kBrick - 1;
        VolumeDesc bd;
        bd.dims = ivec3(kStored);
        Volume bi(bd);
        bd.type = VoxelType::U16;
        Volume bl(bd);
        for (int z = 0; z < kStored; ++z)
          for (int y = 0; y < kStored; ++y)
            for (int x = 0; x < kStored; ++x) {
              const ivec3 v = glm::clamp(first + ivec3(x, y, z), ivec3(0), d.dims - 1);
              bi.set(x, y, z, intensity.view().value(v.x, v.y, v.z));
              bl.set(x, y, z, float(lv.label(v.x, v.y, v.z)));
            }
        const VolumeView blv = bl.view();
        for (int cz = 0; cz < 2; ++cz)
          for (int cy = 0; cy < 2; ++cy)
            for (int cx = 0; cx < 2; ++cx) {
              const ivec3 c = ivec3(bx, by, bz) * 2 + ivec3(cx, cy, cz);
              if (!g.inside(c)) continue;
              const BlockMetadata whole = compute_block_metadata(g, intensity.view(), &lv, c.x, c.y, c.z);
              const BlockMetadata brick = compute_block_metadata(bi.view(), &blv, first, d.dims, c * 4, 4);
              EXPECT_EQ(brick.min, whole.min);
              EXPECT_EQ(brick.max, whole.max);
              EXPECT_EQ(brick.labels, whole.labels);
              EXPECT_TRUE(brick.has_labels && brick.computed);
              ++checked;
            }
      }
  EXPECT_EQ(checked, int(g.block_count()));
}

// A NaN voxel anywhere in a block (not only its first) makes the block's range everything: a NaN sample
// reads the transfer function's low end, so a block whose finite values are transparent may still show
// it, and culling must not call it EMPTY. The skipping methods then agree with no skipping.
TEST(BlockMetadata, NanVoxelsMakeTheRangeEverything) {
  VolumeDesc d;
  d.dims = ivec3(24, 20, 18);
  d.type = VoxelType::F32;
  Volume v(d);
  for (int z = 0; z < d.dims.z; ++z)
    for (int y = 0; y < d.dims.y; ++y)
      for (int x = 0; x < d.dims.x; ++x) v.set(x, y, z, 200.0f);
  v.set(13, 9, 7, std::numeric_limits<float>::quiet_NaN());  // not the first voxel of any block
  const BlockGrid g = make_block_grid(d.dims, d.spacing, 8);
  const BlockMetadata m = compute_block_metadata(g, v.view(), nullptr, 1, 1, 0);
  EXPECT_EQ(m.min, -std::numeric_limits<float>::infinity());
  EXPECT_EQ(m.max, std::numeric_limits<float>::infinity());
  const BlockMetadata clean = compute_block_metadata(g, v.view(), nullptr, 0, 0, 2);
  EXPECT_EQ(clean.min, 200.0f);
  // Opaque only at the low end (where NaN reads), transparent at 200.
  const TransferFunction tf({{0.0f, {1, 0, 0, 0.8f}}, {10.0f, {0, 0, 0, 0}}, {255.0f, {0, 0, 0, 0}}});
  CullParams p;
  p.tf = &tf;
  EXPECT_EQ(classify_block(m, p), OccupancyClass::NonEmpty);
  EXPECT_EQ(classify_block(clean, p), OccupancyClass::Empty);
  Scene scene{&v, nullptr, &tf, nullptr, default_camera(d.extent())};
  RenderSettings s;
  s.width = s.height = 40;
  std::vector<Frame> frames;
  for (SkipMethod method : {SkipMethod::None, SkipMethod::BBox, SkipMethod::Octree, SkipMethod::SparseLeap}) {
    s.method = method;
    frames.push_back(InCoreRenderer().render(scene, s));
  }
  float alpha = 0.0f;
  for (const vec4& c : frames[0].image.rgba) alpha += c.w;
  EXPECT_GT(alpha, 0.0f) << "the NaN voxel shows";
  for (std::size_t k = 1; k < frames.size(); ++k) {
    EXPECT_EQ(std::memcmp(frames[k].image.rgba.data(), frames[0].image.rgba.data(),
                          frames[0].image.rgba.size() * sizeof(vec4)), 0) << to_string(s.method);
  }
}

// compute_box_metadata reads each box with the voxel type known; it must give what reading every voxel
// through VolumeView::value and ::label gives, for every voxel and label type, a separate low and high
// view (the bounds pyramid's min and max levels), any box, and float NaNs anywhere.
RC_GTEST_PROP(BlockMetadata, BoxMetadataEqualsAVoxelByVoxelScan, ()) {
  const VoxelType type = *rc::gen::element(VoxelType::U8, VoxelType::U16, VoxelType::F32);
  const VoxelType label_type = *rc::gen::element(VoxelType::U8, VoxelType::U16, VoxelType::U32);
  const ivec3 dims(*rc::gen::inRange(1, 12), *rc::gen::inRange(1, 12), *rc::gen::inRange(1, 12));
  const bool split = *rc::gen::arbitrary<bool>();  // low and high distinct views
  const bool with_labels = *rc::gen::arbitrary<bool>();
  const int nan_at = type == VoxelType::F32 && *rc::gen::inRange(0, 4) == 0
                         ? *rc::gen::inRange(0, dims.x * dims.y * dims.z)
                         : -1;
  const std::size_t n = std::size_t(dims.x) * dims.y * dims.z;
  const std::vector<int> raw = *rc::gen::container<std::vector<int>>(n, rc::gen::inRange(0, 70000));
  const std::vector<int> rise = *rc::gen::container<std::vector<int>>(n, rc::gen::inRange(0, 9));
  const std::vector<int> ids = *rc::gen::container<std::vector<int>>(n, rc::gen::inRange(0, 5));
  Volume low(VolumeDesc{dims, vec3(1.0f), type}), high(low.desc()), labels(VolumeDesc{dims, vec3(1.0f), label_type});
  const float top = type == VoxelType::U8 ? 255.0f : 65535.0f;
  // Ids spread over the label type's range (u32 ids beyond 2^24 would not survive Volume::set's float).
  const float id_scale = label_type == VoxelType::U8 ? 50.0f : label_type == VoxelType::U16 ? 16000.0f : 4000000.0f;
  std::size_t i = 0;
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x, ++i) {
        const float v = type == VoxelType::F32 ? float(raw[i]) * 0.25f - 9000.0f : std::min(float(raw[i]), top);
        low.set(x, y, z, int(i) == nan_at ? std::nanf("") : v);
        high.set(x, y, z, type == VoxelType::F32 ? v + float(rise[i]) : std::min(v + float(rise[i]), top));
        labels.set(x, y, z, float(ids[i]) * id_scale);
      }
  ivec3 lo, hi;
  for (int a = 0; a < 3; ++a) {
    lo[a] = *rc::gen::inRange(0, dims[a]);
    hi[a] = *rc::gen::inRange(lo[a] + 1, dims[a] + 1);
  }
  const VolumeView lv = low.view(), hv = split ? high.view() : low.view(), bv = labels.view();
  const BlockMetadata m = compute_box_metadata(lv, hv, with_labels ? &bv : nullptr, lo, hi);
  float want_min = std::numeric_limits<float>::infinity(), want_max = -std::numeric_limits<float>::infinity();
  bool nan = false;
  std::set<std::uint32_t> want_ids;
  for (int z = lo.z; z < hi.z; ++z)
    for (int y = lo.y; y < hi.y; ++y)
      for (int x = lo.x; x < hi.x; ++x) {
        const float a = lv.value(x, y, z), b = hv.value(x, y, z);
        nan = nan || std::isnan(a) || std::isnan(b);
        want_min = std::min(want_min, a);
        want_max = std::max(want_max, b);
        want_ids.insert(bv.label(x, y, z));
      }
  RC_ASSERT(m.computed);
  if (nan) {
    RC_ASSERT(m.min == -std::numeric_limits<float>::infinity());
    RC_ASSERT(m.max == std::numeric_limits<float>::infinity());
  } else {
    RC_ASSERT(m.min == want_min);
    RC_ASSERT(m.max == want_max);
  }
  RC_ASSERT(m.has_labels == with_labels);
  if (with_labels) {
    RC_ASSERT(m.labels == std::vector<std::uint32_t>(want_ids.begin(), want_ids.end()));
  } else {
    RC_ASSERT(m.labels.empty());
  }
}

}  // namespace
}  // namespace sl
