#include "cache/volume_source.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <memory>
#include <vector>

#include "core/scene/generate.h"
#include "cache/synthetic/procedural_neurites.h"
#include "core/util/error.h"

namespace sl {
namespace {

std::shared_ptr<Volume> ramp(ivec3 dims, VoxelType t) {
  auto v = std::make_shared<Volume>(VolumeDesc{dims, vec3(1.0f), t});
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x) {
        const float f = float((x * 7 + y * 13 + z * 29) % 251);
        v->set(x, y, z, t == VoxelType::F32 ? f * 0.37f - 20.0f : f);
      }
  return v;
}

// Level voxel a stored voxel of a brick holds (brick.h: clamp to the level's edge).
ivec3 source_voxel(const BrickLayout& l, BrickId id, ivec3 s) {
  return glm::clamp(l.brick_origin(id) - 1 + s, ivec3(0), l.dims(id.level()) - 1);
}

void expect_brick_equals(const BrickLayout& l, BrickId id, const Volume& level, std::span<const std::byte> brick) {
  const int n = l.stored_size(), es = voxel_size(level.type());
  for (int z = 0; z < n; ++z)
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) {
        const ivec3 v = source_voxel(l, id, {x, y, z});
        const std::byte* want = level.data() + level.view().index(v.x, v.y, v.z) * std::uint64_t(es);
        const std::byte* got = brick.data() + std::size_t(l.stored_index({x, y, z})) * std::size_t(es);
        ASSERT_EQ(std::memcmp(want, got, std::size_t(es)), 0)
            << to_string(id) << " stored (" << x << "," << y << "," << z << ")";
      }
}

TEST(MemoryVolumeSource, Level0BricksEqualTheVolumeIncludingApron) {
  for (const VoxelType t : {VoxelType::U8, VoxelType::U16, VoxelType::F32}) {
    SCOPED_TRACE(to_string(t));
    const ivec3 dims(37, 20, 19);
    auto vol = ramp(dims, t);
    auto labels = ramp(dims, VoxelType::U16);
    const MemoryVolumeSource src(vol, labels, "ramp.nrrd");
    EXPECT_EQ(src.desc().dims, dims);
    EXPECT_TRUE(src.has_labels());
    EXPECT_EQ(src.label_type(), VoxelType::U16);
    const BrickLayout l = BrickLayout::make(src.desc(), 8);
    std::vector<std::byte> in(l.stored_voxels() * std::size_t(voxel_size(t)));
    std::vector<std::byte> lab(l.stored_voxels() * 2);
    const ivec3 n = l.bricks(0);
    for (int z = 0; z < n.z; ++z)
      for (int y = 0; y < n.y; ++y)
        for (int x = 0; x < n.x; ++x) {
          const BrickId id = BrickId::pack(0, {x, y, z});
          src.read_brick(l, id, in, lab);
          expect_brick_equals(l, id, *vol, in);
          expect_brick_equals(l, id, *labels, lab);
        }
    // Labels are optional per read.
    src.read_brick(l, BrickId::pack(0, {1, 1, 1}), in, {});
  }
}

TEST(MemoryVolumeSource, ReductionMeanAndLabelModeByHand) {
  // 3x2x2: the level-1 voxel 0 averages children x in {0,1}; voxel 1 holds only x = 2 (odd edge).
  auto v = std::make_shared<Volume>(VolumeDesc{{3, 2, 2}, vec3(1.0f), VoxelType::U8});
  auto lab = std::make_shared<Volume>(VolumeDesc{{3, 2, 2}, vec3(1.0f), VoxelType::U32});
  // Children of voxel 0: values 0,1,2,3,4,5,6,9 -> sum 30 / 8 = 3.75 -> 4.
  const int vals[2][2][2] = {{{0, 1}, {2, 3}}, {{4, 5}, {6, 9}}};
  // Labels of voxel 0: 7 twice, 9 twice, zeros four times: tie between 7 and 9 -> 9 (larger id).
  const int labs[2][2][2] = {{{7, 0}, {9, 0}}, {{0, 7}, {0, 9}}};
  for (int z = 0; z < 2; ++z)
    for (int y = 0; y < 2; ++y) {
      for (int x = 0; x < 2; ++x) {
        v->set(x, y, z, float(vals[z][y][x]));
        lab->set(x, y, z, float(labs[z][y][x]));
      }
      v->set(2, y, z, float(10 + y + 2 * z));  // 10, 11, 12, 13: mean 11.5 -> 12 (half up)
      lab->set(2, y, z, z == 0 && y == 0 ? 0.0f : 5.0f);
    }
  const MemoryVolumeSource src(v, lab);
  ASSERT_GE(src.levels(), 3);
  const Volume& l1 = src.level(1);
  EXPECT_EQ(l1.dims(), ivec3(2, 1, 1));
  EXPECT_EQ(l1.value(0, 0, 0), 4.0f);
  EXPECT_EQ(l1.value(1, 0, 0), 12.0f);
  EXPECT_EQ(src.label_level(1)->label(0, 0, 0), 9u);
  EXPECT_EQ(src.label_level(1)->label(1, 0, 0), 5u);  // zeros never win
  // Level 2: mean of the two level-1 voxels (4 + 12) / 2 = 8; labels tie 9 vs 5 -> 9.
  EXPECT_EQ(src.level(2).dims(), ivec3(1, 1, 1));
  EXPECT_EQ(src.level(2).value(0, 0, 0), 8.0f);
  EXPECT_EQ(src.label_level(2)->label(0, 0, 0), 9u);

  // f32 means are not rounded.
  auto f = std::make_shared<Volume>(VolumeDesc{{2, 1, 1}, vec3(1.0f), VoxelType::F32});
  f->set(0, 0, 0, 1.0f);
  f->set(1, 0, 0, 2.5f);
  EXPECT_EQ(MemoryVolumeSource(f).level(1).value(0, 0, 0), 1.75f);
}

TEST(MemoryVolumeSource, CoarseBricksComeFromThePyramid) {
  const GeneratedVolume g = generate_volume("neurites", {70, 45, 33}, 3);
  auto vol = std::make_shared<Volume>(g.intensity);
  auto lab = std::make_shared<Volume>(g.labels);
  const MemoryVolumeSource src(vol, lab, "neurites");
  // Pyramid costs about 1/7 extra (less: the divisions round up).
  const double extra = double(src.pyramid_bytes()) / double(vol->desc().byte_size() + lab->desc().byte_size());
  EXPECT_GT(extra, 0.12);
  EXPECT_LT(extra, 0.25);
  const BrickLayout l = BrickLayout::make(src.desc(), 8);
  std::vector<std::byte> in(l.stored_voxels()), lb(l.stored_voxels() * 2);
  for (int level = 1; level < l.levels; ++level) {
    const ivec3 n = l.bricks(level);
    for (int z = 0; z < n.z; ++z)
      for (int y = 0; y < n.y; ++y)
        for (int x = 0; x < n.x; ++x) {
          const BrickId id = BrickId::pack(level, {x, y, z});
          src.read_brick(l, id, in, lb);
          expect_brick_equals(l, id, src.level(level), in);
          expect_brick_equals(l, id, *src.label_level(level), lb);
        }
  }
  // A level-1 voxel is the rounded mean of its level-0 children.
  const Volume& l1 = src.level(1);
  for (int z = 0; z < l1.dims().z; ++z)
    for (int y = 0; y < l1.dims().y; ++y)
      for (int x = 0; x < l1.dims().x; ++x) {
        int sum = 0, n = 0;
        for (int k = 2 * z; k < std::min(2 * z + 2, 33); ++k)
          for (int j = 2 * y; j < std::min(2 * y + 2, 45); ++j)
            for (int i = 2 * x; i < std::min(2 * x + 2, 70); ++i, ++n) sum += int(vol->value(i, j, k));
        ASSERT_EQ(int(l1.value(x, y, z)), (sum + n / 2) / n);
      }
}

TEST(MemoryVolumeSource, RejectsBadLabels) {
  auto v = ramp({4, 4, 4}, VoxelType::U8);
  EXPECT_THROW(MemoryVolumeSource(v, ramp({4, 4, 4}, VoxelType::F32), "x.nrrd"), InputError);
  try {
    MemoryVolumeSource(v, ramp({4, 4, 5}, VoxelType::U16), "x.nrrd");
    ADD_FAILURE() << "no throw";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "x.nrrd");
  }
}

TEST(VolumeSpec, ParsesAndRejects) {
  EXPECT_TRUE(is_procedural_spec("procedural:neurites:8x8x8"));
  EXPECT_FALSE(is_procedural_spec("data/volume.nrrd"));
  const auto src = parse_volume_spec("procedural:neurites:32768x32768x8192");
  EXPECT_EQ(src->desc().dims, ivec3(32768, 32768, 8192));
  EXPECT_EQ(src->desc().type, VoxelType::U8);
  EXPECT_TRUE(src->has_labels());
  EXPECT_EQ(src->label_type(), VoxelType::U32);
  EXPECT_EQ(src->name(), "procedural:neurites:32768x32768x8192");
  EXPECT_NO_THROW(parse_volume_spec("procedural:neurites:5x6x7:42"));
  for (const char* bad : {"procedural:neurites:", "procedural:neurites:10x10", "procedural:neurites:10x0x10",
                          "procedural:neurites:10xx10", "procedural:neurites:-5x10x10", "procedural:neurites:8x8x8:",
                          "procedural:neurites:8x8x8:seed", "procedural:blobs:8x8x8", "neurites:8x8x8",
                          "procedural:neurites:99999999x8x8", "procedural:neurites:8x8x8x8"}) {
    try {
      parse_volume_spec(bad);
      ADD_FAILURE() << "no throw for " << bad;
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), bad);
      EXPECT_NE(std::string(e.what()).find("expected procedural:neurites:XxYxZ"), std::string::npos);
    }
  }
}

// without_labels: the same intensity and the same culling ranges as the source it wraps, bricks read
// without their labels (the procedural source then skips their reduction) and bounds without label
// lists; a source without labels is returned as it is.
void expect_same_intensity_without_labels(const std::shared_ptr<const VolumeSource>& src, int brick, int block) {
  ASSERT_TRUE(src->has_labels());
  const std::shared_ptr<const VolumeSource> bare = without_labels(src);
  EXPECT_FALSE(bare->has_labels());
  EXPECT_EQ(bare->name(), src->name());
  EXPECT_EQ(bare->pyramid(), src->pyramid());
  EXPECT_EQ(without_labels(bare), bare);
  const BrickLayout l = BrickLayout::make(src->desc(), brick);
  const std::size_t n = l.stored_voxels();
  std::vector<std::byte> want(n * std::size_t(voxel_size(src->desc().type))), got(want.size());
  std::vector<std::byte> labels(n * std::size_t(voxel_size(src->label_type())));
  int coarse_with_ids = 0;
  for (int level = 0; level < l.levels; ++level) {
    const ivec3 nb = l.bricks(level);
    // The first, middle and last brick of each level.
    for (const ivec3 b : {ivec3(0), nb / 2, nb - 1}) {
      const BrickId id = BrickId::pack(level, b);
      std::vector<BlockMetadata> want_bounds, got_bounds;
      src->read_brick_bounded(l, id, want, labels, block, want_bounds);
      std::fill(got.begin(), got.end(), std::byte{0xA5});
      bare->read_brick_bounded(l, id, got, {}, block, got_bounds);
      ASSERT_EQ(std::memcmp(want.data(), got.data(), want.size()), 0) << to_string(id);
      std::fill(got.begin(), got.end(), std::byte{0xA5});
      bare->read_brick(l, id, got, {});
      ASSERT_EQ(std::memcmp(want.data(), got.data(), want.size()), 0) << to_string(id);
      ASSERT_EQ(got_bounds.size(), want_bounds.size()) << to_string(id);
      std::vector<BlockMetadata> bound(want_bounds.size());
      const bool bounds = level > 0 && bare->bound_blocks(l, level, block, brick_culling_blocks(l, id, block), bound);
      for (std::size_t i = 0; i < want_bounds.size(); ++i) {
        EXPECT_EQ(got_bounds[i].min, want_bounds[i].min) << to_string(id);
        EXPECT_EQ(got_bounds[i].max, want_bounds[i].max) << to_string(id);
        EXPECT_FALSE(got_bounds[i].has_labels);
        EXPECT_TRUE(got_bounds[i].labels.empty());
        coarse_with_ids += want_bounds[i].has_labels && !want_bounds[i].labels.empty();
        if (bounds) {
          EXPECT_EQ(bound[i].min, want_bounds[i].min) << to_string(id);
          EXPECT_EQ(bound[i].max, want_bounds[i].max) << to_string(id);
          EXPECT_FALSE(bound[i].has_labels);
        }
      }
    }
  }
  EXPECT_GT(coarse_with_ids, 0) << "the wrapped source's bounds must list labels for the test to mean anything";
}

TEST(WithoutLabels, MemorySourceGivesTheSameIntensityAndRanges) {
  const GeneratedVolume g = generate_volume("neurites", {70, 45, 33}, 3);
  auto src = std::make_shared<MemoryVolumeSource>(std::make_shared<Volume>(g.intensity),
                                                  std::make_shared<Volume>(g.labels), "neurites", PyramidKind::Max);
  expect_same_intensity_without_labels(src, 8, 4);
  auto bare = std::make_shared<MemoryVolumeSource>(std::make_shared<Volume>(g.intensity), nullptr, "bare");
  EXPECT_EQ(without_labels(bare).get(), bare.get());
}

TEST(WithoutLabels, ProceduralSourceGivesTheSameIntensityAndRangesOnEveryMethod) {
  // Brick 16 over 600x520x300: levels 0-2 exact, 3-4 walked, 5-6 hashed, and coarser.
  auto src = std::make_shared<ProceduralNeuritesSource>(ivec3(600, 520, 300), 4);
  expect_same_intensity_without_labels(src, 16, 8);
}

}  // namespace
}  // namespace sl
