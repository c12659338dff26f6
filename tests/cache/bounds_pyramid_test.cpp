// The bounds pyramid for culling (DESIGN.md "Virtual memory": "metadata is a min/max pyramid"; cache/pyramid.h,
// VolumeSource::bound_blocks): a coarse voxel bounds every level-0 voxel below it, and a coarse
// culling block's metadata covers every level-0 voxel below its dilated box — exactly, not just
// conservatively — for in-memory volumes and the procedural source's exact levels.
#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <set>
#include <vector>

#include "cache/pyramid.h"
#include "core/scene/generate.h"
#include "cache/synthetic/procedural_neurites.h"
#include "cache/volume_source.h"
#include "core/util/rng.h"

namespace sl {
namespace {

// Level-0 voxels below level-l voxels [first, end), clamped to the volume.
void level0_box(ivec3 dims0, int level, ivec3 first, ivec3 end, ivec3& lo, ivec3& hi) {
  lo = first * (1 << level);
  hi = glm::min(end * (1 << level), dims0);
}

struct Brute {
  float min = std::numeric_limits<float>::infinity(), max = -std::numeric_limits<float>::infinity();
  std::set<std::uint32_t> labels;
};

Brute brute(const Volume& v, const Volume* labels, ivec3 lo, ivec3 hi) {
  Brute b;
  for (int z = lo.z; z < hi.z; ++z)
    for (int y = lo.y; y < hi.y; ++y)
      for (int x = lo.x; x < hi.x; ++x) {
        b.min = std::min(b.min, v.value(x, y, z));
        b.max = std::max(b.max, v.value(x, y, z));
        if (labels) b.labels.insert(labels->label(x, y, z));
      }
  return b;
}

std::shared_ptr<Volume> random_volume(ivec3 dims, VoxelType t, std::uint32_t seed, std::uint32_t range) {
  auto v = std::make_shared<Volume>(VolumeDesc{dims, vec3(1.0f), t});
  SplitMix64 rng(seed);
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x) {
        // Mostly background, like segmented data: long runs, a few values.
        const std::uint32_t r = std::uint32_t(rng.next() >> 32);
        v->set(x, y, z, (r & 7u) == 0 ? float(1 + (r >> 8) % range) : 0.0f);
      }
  return v;
}

TEST(BoundsPyramid, MinMaxAndLabelSetsBoundEveryLevelZeroVoxel) {
  const ivec3 dims(37, 20, 11);  // odd edges: the last voxel of a level covers what exists
  const auto v = random_volume(dims, VoxelType::U16, 3, 60000);
  const auto lab = random_volume(dims, VoxelType::U16, 4, 9);
  Volume lo = *v, hi = *v;
  LabelSetLevel sets;
  for (int l = 1; l <= 4; ++l) {
    SCOPED_TRACE("level " + std::to_string(l));
    VolumeDesc d = lo.desc();
    d.dims = (d.dims + 1) / 2;
    Volume nlo(d), nhi(d);
    reduce_min(VoxelType::U16, lo.data(), lo.dims(), nlo.data(), 0, d.dims.z);
    reduce_max(VoxelType::U16, hi.data(), hi.dims(), nhi.data(), 0, d.dims.z);
    sets = l == 1 ? reduce_label_sets(*lab) : reduce_label_sets(sets);
    lo = std::move(nlo);
    hi = std::move(nhi);
    ASSERT_EQ(sets.sets.dims(), d.dims);
    for (int z = 0; z < d.dims.z; ++z)
      for (int y = 0; y < d.dims.y; ++y)
        for (int x = 0; x < d.dims.x; ++x) {
          ivec3 a, b;
          level0_box(dims, l, ivec3(x, y, z), ivec3(x, y, z) + 1, a, b);
          const Brute want = brute(*v, lab.get(), a, b);
          ASSERT_EQ(lo.value(x, y, z), want.min);
          ASSERT_EQ(hi.value(x, y, z), want.max);
          const auto s = sets.set(sets.sets.as<std::uint32_t>()[sets.sets.view().index(x, y, z)]);
          ASSERT_EQ(std::vector<std::uint32_t>(s.begin(), s.end()),
                    std::vector<std::uint32_t>(want.labels.begin(), want.labels.end()));
        }
  }
  EXPECT_LT(sets.offsets.size() - 1, std::size_t(sets.sets.desc().voxel_count()) + 1) << "sets are interned";
}

TEST(BoundsPyramid, FloatNanPropagates) {
  auto v = std::make_shared<Volume>(VolumeDesc{ivec3(4, 4, 4), vec3(1.0f), VoxelType::F32});
  v->set(3, 0, 0, std::numeric_limits<float>::quiet_NaN());
  VolumeDesc d = v->desc();
  d.dims = ivec3(2);
  Volume lo(d), hi(d);
  reduce_min(VoxelType::F32, v->data(), v->dims(), lo.data(), 0, 2);
  reduce_max(VoxelType::F32, v->data(), v->dims(), hi.data(), 0, 2);
  EXPECT_TRUE(std::isnan(lo.value(1, 0, 0)) && std::isnan(hi.value(1, 0, 0)));
  EXPECT_EQ(lo.value(0, 0, 0), 0.0f);
  // Block metadata over a NaN bound is the conservative "anything".
  const BlockMetadata m = compute_box_metadata(lo.view(), hi.view(), nullptr, ivec3(0), ivec3(2));
  EXPECT_EQ(m.min, -std::numeric_limits<float>::infinity());
  EXPECT_EQ(m.max, std::numeric_limits<float>::infinity());
}

// Every coarse culling block of every level: the bounds equal the brute force over the level-0
// voxels below its dilated box, and contain the metadata of the level's own (mean) voxels.
TEST(BoundsPyramid, MemorySourceBoundsEveryCoarseBlockExactly) {
  const ivec3 dims(70, 45, 33);
  const auto v = random_volume(dims, VoxelType::U8, 5, 250);
  const auto lab = random_volume(dims, VoxelType::U32, 6, 40);
  const MemoryVolumeSource src(v, lab, "random");
  EXPECT_GT(src.bounds_bytes(), 0u);
  const BrickLayout layout = BrickLayout::make(v->desc(), 8, "random");
  const int block = 4;
  for (int l = 1; l < layout.levels; ++l) {
    SCOPED_TRACE("level " + std::to_string(l));
    const ivec3 ld = layout.dims(l), nb = (ld + block - 1) / block;
    std::vector<ivec3> blocks;
    for (int z = 0; z < nb.z; ++z)
      for (int y = 0; y < nb.y; ++y)
        for (int x = 0; x < nb.x; ++x) blocks.push_back(ivec3(x, y, z));
    std::vector<BlockMetadata> out(blocks.size());
    ASSERT_TRUE(src.bound_blocks(layout, l, block, blocks, out));
    for (std::size_t i = 0; i < blocks.size(); ++i) {
      ivec3 f, e, a, b;
      dilated_block(ld, blocks[i] * block, block, f, e);
      level0_box(dims, l, f, e, a, b);
      const Brute want = brute(*v, lab.get(), a, b);
      ASSERT_TRUE(out[i].computed && out[i].has_labels);
      ASSERT_EQ(out[i].min, want.min);
      ASSERT_EQ(out[i].max, want.max);
      ASSERT_EQ(out[i].labels, std::vector<std::uint32_t>(want.labels.begin(), want.labels.end()));
      const VolumeView own_labels = src.label_level(l)->view();
      const BlockMetadata own =
          compute_block_metadata(src.level(l).view(), &own_labels, ivec3(0), ld, blocks[i] * block, block);
      EXPECT_LE(out[i].min, own.min);
      EXPECT_GE(out[i].max, own.max);
      EXPECT_TRUE(std::includes(out[i].labels.begin(), out[i].labels.end(), own.labels.begin(), own.labels.end()));
    }
  }
}

// Exact levels: the bounds of the level-0 voxels the procedural source synthesises; splatted
// levels: the whole u8 range, labels not listed (no culling by labels there).
TEST(BoundsPyramid, ProceduralSourceBoundsItsLevels) {
  const ProceduralNeuritesSource src(ivec3(160, 96, 80), 7);
  const BrickLayout layout = BrickLayout::make(src.desc(), 8, src.name());
  const int block = 8;
  const std::vector<ivec3> blocks = {ivec3(0, 0, 0), ivec3(1, 0, 1), ivec3(2, 1, 1)};
  bool tubes = false;
  for (int l = 1; l < layout.levels; ++l) {
    SCOPED_TRACE("level " + std::to_string(l));
    const ivec3 ld = layout.dims(l);
    std::vector<ivec3> inside;
    for (const ivec3 c : blocks) {
      if (glm::all(glm::lessThan(c * block, ld))) inside.push_back(c);
    }
    std::vector<BlockMetadata> out(inside.size());
    ASSERT_TRUE(src.bound_blocks(layout, l, block, inside, out));
    for (std::size_t i = 0; i < inside.size(); ++i) {
      ASSERT_TRUE(out[i].computed);
      if (ProceduralNeuritesSource::method(l) != ProceduralNeuritesSource::Method::Exact) {
        EXPECT_EQ(out[i].min, 0.0f);
        EXPECT_EQ(out[i].max, 255.0f);
        EXPECT_FALSE(out[i].has_labels);
        continue;
      }
      ivec3 f, e, a, b;
      dilated_block(ld, inside[i] * block, block, f, e);
      level0_box(src.desc().dims, l, f, e, a, b);
      const ivec3 n = b - a;
      Volume v0(VolumeDesc{n, vec3(1.0f), VoxelType::U8}), l0(VolumeDesc{n, vec3(1.0f), VoxelType::U32});
      src.synthesize(0, a, n, v0.as<std::uint8_t>(), l0.as<std::uint32_t>());
      const Brute want = brute(v0, &l0, ivec3(0), n);
      EXPECT_EQ(out[i].min, want.min);
      EXPECT_EQ(out[i].max, want.max);
      EXPECT_EQ(out[i].labels, std::vector<std::uint32_t>(want.labels.begin(), want.labels.end()));
      tubes = tubes || want.max > 0.0f;
    }
  }
  EXPECT_TRUE(tubes) << "blocks without a tube test nothing";
}

// A coarse brick read with its bounds (what the loader does): the same voxels as read_brick, and the
// same bounds as bound_blocks over the brick's culling blocks — on the exact levels taken from the
// level-0 voxels the read synthesises slab by slab, elsewhere from bound_blocks itself. Edge bricks
// (clamped apron, partial blocks) included; both pyramids.
TEST(BoundsPyramid, ProceduralReadWithBoundsEqualsReadThenBounds) {
  for (const PyramidKind kind : {PyramidKind::Mean, PyramidKind::Max}) {
    const ProceduralNeuritesSource src(ivec3(150, 90, 70), 5, "procedural:neurites", kind);
    const BrickLayout layout = BrickLayout::make(src.desc(), 16, src.name());
    const std::size_t n = layout.stored_voxels();
    bool tubes = false;
    for (int l = 0; l < layout.levels; ++l) {
      const ivec3 bricks = layout.bricks(l);
      for (const ivec3 c : {ivec3(0), bricks / 2, bricks - 1}) {
        for (const int block : {8, 16}) {
          const BrickId id = BrickId::pack(l, c);
          SCOPED_TRACE(to_string(id) + ", block " + std::to_string(block));
          std::vector<std::byte> i1(n), l1(n * 4), i2(n), l2(n * 4);
          src.read_brick(layout, id, i1, l1);
          std::vector<BlockMetadata> bounds;
          src.read_brick_bounded(layout, id, i2, l2, block, bounds);
          EXPECT_EQ(i1, i2);
          EXPECT_EQ(l1, l2);
          if (l == 0) {
            EXPECT_TRUE(bounds.empty());
            continue;
          }
          const std::vector<ivec3> blocks = brick_culling_blocks(layout, id, block);
          std::vector<BlockMetadata> want(blocks.size());
          ASSERT_TRUE(src.bound_blocks(layout, l, block, blocks, want));
          ASSERT_EQ(bounds.size(), want.size());
          for (std::size_t b = 0; b < want.size(); ++b) {
            EXPECT_EQ(bounds[b].computed, want[b].computed);
            EXPECT_EQ(bounds[b].min, want[b].min);
            EXPECT_EQ(bounds[b].max, want[b].max);
            EXPECT_EQ(bounds[b].has_labels, want[b].has_labels);
            EXPECT_EQ(bounds[b].labels, want[b].labels);
            tubes = tubes || (want[b].has_labels && want[b].labels.size() > 1);
          }
        }
      }
    }
    EXPECT_TRUE(tubes) << "bricks without a labelled tube test nothing";
  }
}

// The parts of a box merge to the box: ranges and label sets.
TEST(BoundsPyramid, MergedPartsEqualTheWhole) {
  const ProceduralNeuritesSource src(ivec3(160, 96, 80), 7);
  const ivec3 n = src.desc().dims;
  Volume v(VolumeDesc{n, vec3(1.0f), VoxelType::U8}), lab(VolumeDesc{n, vec3(1.0f), VoxelType::U32});
  src.synthesize(0, ivec3(0), n, v.as<std::uint8_t>(), lab.as<std::uint32_t>());
  const VolumeView iv = v.view(), lv = lab.view();
  const BlockMetadata whole = compute_box_metadata(iv, iv, &lv, ivec3(0), n);
  for (const int cut : {1, 7, 40, 79}) {
    BlockMetadata merged = compute_box_metadata(iv, iv, &lv, ivec3(0), ivec3(n.x, n.y, cut));
    merge_box_metadata(merged, compute_box_metadata(iv, iv, &lv, ivec3(0, 0, cut), n));
    EXPECT_EQ(merged.min, whole.min);
    EXPECT_EQ(merged.max, whole.max);
    EXPECT_EQ(merged.labels, whole.labels);
  }
  EXPECT_GT(whole.labels.size(), 2u);
}

// reduce_min and reduce_max take whole 2³ groups four source rows at a time for integer types and the
// partial groups at odd far faces one voxel at a time: every coarse voxel must be the least / largest of
// the (up to) eight voxels below it, for any dims, odd or even.
RC_GTEST_PROP(BoundsPyramid, IntegerMinAndMaxReductionsEqualAScanOfTheVoxelsBelow, ()) {
  const VoxelType type = *rc::gen::element(VoxelType::U8, VoxelType::U16);
  const ivec3 d(*rc::gen::inRange(1, 19), *rc::gen::inRange(1, 19), *rc::gen::inRange(1, 19));
  const int top = type == VoxelType::U8 ? 255 : 65535;
  // Dense values, or mostly background as segmented data is.
  const bool sparse = *rc::gen::arbitrary<bool>();
  const auto v = sparse ? random_volume(d, type, *rc::gen::arbitrary<std::uint32_t>(), std::uint32_t(top))
                        : std::make_shared<Volume>(VolumeDesc{d, vec3(1.0f), type});
  if (!sparse) {
    const std::vector<int> values =
        *rc::gen::container<std::vector<int>>(std::size_t(d.x) * d.y * d.z, rc::gen::inRange(0, top + 1));
    std::size_t i = 0;
    for (int z = 0; z < d.z; ++z)
      for (int y = 0; y < d.y; ++y)
        for (int x = 0; x < d.x; ++x) v->set(x, y, z, float(values[i++]));
  }
  const ivec3 h = (d + 1) / 2;
  std::vector<std::byte> lo(std::size_t(h.x) * h.y * h.z * std::size_t(voxel_size(type))), hi(lo.size());
  reduce_min(type, v->data(), d, lo.data(), 0, h.z);
  reduce_max(type, v->data(), d, hi.data(), 0, h.z);
  const VolumeView lv{lo.data(), h, vec3(2.0f), type}, hv{hi.data(), h, vec3(2.0f), type};
  for (int z = 0; z < h.z; ++z)
    for (int y = 0; y < h.y; ++y)
      for (int x = 0; x < h.x; ++x) {
        const Brute b = brute(*v, nullptr, 2 * ivec3(x, y, z), glm::min(2 * ivec3(x, y, z) + 2, d));
        RC_ASSERT(lv.value(x, y, z) == b.min);
        RC_ASSERT(hv.value(x, y, z) == b.max);
      }
}

}  // namespace
}  // namespace sl
