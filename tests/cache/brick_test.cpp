#include "cache/brick.h"

#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include "core/util/error.h"

namespace sl {
namespace {

ivec3 ceil_div(ivec3 a, int b) { return (a + b - 1) / b; }

RC_GTEST_PROP(BrickId, PackUnpackRoundTrip, ()) {
  const int level = *rc::gen::inRange(0, kMaxBrickLevels);
  const auto axis = rc::gen::inRange(0, 1 << BrickId::kAxisBits);
  const ivec3 c(*axis, *axis, *axis);
  const BrickId id = BrickId::pack(level, c);
  RC_ASSERT(id.valid());
  RC_ASSERT(id.level() == level);
  RC_ASSERT(id.coord() == c);
  RC_ASSERT(id.parent().level() == level + 1);
  RC_ASSERT(id.parent().coord() == c / 2);
}

TEST(BrickId, BitSplitAndInvalid) {
  EXPECT_EQ(BrickId::pack(0, {1, 0, 0}).bits, 1u);
  EXPECT_EQ(BrickId::pack(0, {0, 1, 0}).bits, std::uint64_t(1) << 20);
  EXPECT_EQ(BrickId::pack(0, {0, 0, 1}).bits, std::uint64_t(1) << 40);
  EXPECT_EQ(BrickId::pack(1, {0, 0, 0}).bits, std::uint64_t(1) << 60);
  EXPECT_FALSE(BrickId{}.valid());
  // The largest valid id (level 14, all coordinates maximal) is not the invalid one.
  const int m = (1 << 20) - 1;
  EXPECT_TRUE(BrickId::pack(kMaxBrickLevels - 1, {m, m, m}).valid());
  EXPECT_EQ(to_string(BrickId::pack(2, {3, 4, 5})), "level 2 brick (3, 4, 5)");
}

TEST(BrickLayout, OddDimsDownToOneBrick) {
  const ivec3 dims(97, 131, 73);
  {
    const BrickLayout l = BrickLayout::make(dims, vec3(1.0f), 32);
    ASSERT_EQ(l.levels, 4);
    EXPECT_EQ(l.dims(0), ivec3(97, 131, 73));
    EXPECT_EQ(l.bricks(0), ivec3(4, 5, 3));
    EXPECT_EQ(l.dims(1), ivec3(49, 66, 37));
    EXPECT_EQ(l.bricks(1), ivec3(2, 3, 2));
    EXPECT_EQ(l.dims(2), ivec3(25, 33, 19));
    EXPECT_EQ(l.bricks(2), ivec3(1, 2, 1));
    EXPECT_EQ(l.dims(3), ivec3(13, 17, 10));
    EXPECT_EQ(l.bricks(3), ivec3(1, 1, 1));
    EXPECT_EQ(l.brick_count(0), 60u);
    EXPECT_EQ(l.stored_size(), 34);
    EXPECT_EQ(l.stored_voxels(), 34u * 34u * 34u);
  }
  for (const int b : {8, 16, 32, 64}) {
    SCOPED_TRACE(b);
    const BrickLayout l = BrickLayout::make(dims, vec3(0.5f, 1.0f, 2.0f), b);
    for (int level = 0; level < l.levels; ++level) {
      EXPECT_EQ(l.dims(level), ceil_div(dims, 1 << level));  // ceil(dims / 2^l)
      EXPECT_EQ(l.bricks(level), ceil_div(l.dims(level), b));
      EXPECT_EQ(l.level_spacing(level), vec3(0.5f, 1.0f, 2.0f) * float(1 << level));
    }
    // Stops exactly when one brick holds the level.
    EXPECT_EQ(l.bricks(l.levels - 1), ivec3(1));
    if (l.levels > 1) {
      EXPECT_NE(l.bricks(l.levels - 2), ivec3(1));
    }
  }
  EXPECT_EQ(BrickLayout::make(dims, vec3(1.0f), 8).levels, 6);  // 97,131,73 -> ... -> 4,5,3
  EXPECT_EQ(BrickLayout::make(ivec3(32768, 32768, 8192), vec3(1.0f), 32).levels, 11);
  EXPECT_EQ(BrickLayout::make(ivec3(1, 1, 1), vec3(1.0f), 32).levels, 1);
}

TEST(BrickLayout, RejectsBadInput) {
  try {
    BrickLayout::make(ivec3(10), vec3(1.0f), 24);
    ADD_FAILURE() << "no throw";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "--brick");
  }
  EXPECT_THROW(BrickLayout::make(ivec3(0, 10, 10), vec3(1.0f), 32), InputError);
  // More levels than a BrickId can name.
  EXPECT_THROW(BrickLayout::make(ivec3(1 << 30, 8, 8), vec3(1.0f), 8), InputError);
}

RC_GTEST_PROP(BrickLayout, VoxelToBrickAndLocal, ()) {
  const int b = *rc::gen::element(8, 16, 32, 64);
  const ivec3 dims(*rc::gen::inRange(1, 400), *rc::gen::inRange(1, 400), *rc::gen::inRange(1, 400));
  const BrickLayout l = BrickLayout::make(dims, vec3(1.0f), b);
  const int level = *rc::gen::inRange(0, l.levels);
  const ivec3 d = l.dims(level);
  const ivec3 v(*rc::gen::inRange(0, d.x), *rc::gen::inRange(0, d.y), *rc::gen::inRange(0, d.z));
  const BrickId id = l.brick_of_voxel(level, v);
  RC_ASSERT(l.contains(id));
  const ivec3 local = l.local_voxel(v);
  RC_ASSERT(l.brick_origin(id) + local == v);
  RC_ASSERT(glm::all(glm::greaterThanEqual(local, ivec3(0))) && glm::all(glm::lessThan(local, ivec3(b))));
}

RC_GTEST_PROP(BrickLayout, WorldPointLiesInItsBrickBox, ()) {
  const int b = *rc::gen::element(8, 16, 32);
  const ivec3 dims(*rc::gen::inRange(1, 300), *rc::gen::inRange(1, 300), *rc::gen::inRange(1, 300));
  const vec3 spacing(*rc::gen::inRange(1, 4), *rc::gen::inRange(1, 4), 1.0f);
  const BrickLayout l = BrickLayout::make(dims, spacing, b);
  const int level = *rc::gen::inRange(0, l.levels);
  const vec3 extent = vec3(dims) * spacing;
  const auto unit = rc::gen::inRange(0, 1 << 20);
  const vec3 p = vec3(float(*unit), float(*unit), float(*unit)) / float(1 << 20) * extent;
  const BrickId id = l.brick_at(level, p);
  RC_ASSERT(l.contains(id));
  const WorldBox box = l.brick_box(id);
  RC_ASSERT(glm::all(glm::lessThanEqual(box.lo, p)));
  RC_ASSERT(glm::all(glm::lessThanEqual(p, box.hi)));
  RC_ASSERT(glm::all(glm::lessThanEqual(box.hi, extent)));
}

TEST(BrickLayout, FarBoundaryMapsToLastBrick) {
  const BrickLayout l = BrickLayout::make(ivec3(97, 131, 73), vec3(1.0f), 32);
  EXPECT_EQ(l.brick_at(0, vec3(97.0f, 131.0f, 73.0f)).coord(), ivec3(3, 4, 2));
  EXPECT_EQ(l.brick_at(0, vec3(-1.0f)).coord(), ivec3(0));
  EXPECT_EQ(l.brick_at(1, vec3(96.9f, 0.0f, 0.0f)).coord(), ivec3(1, 0, 0));  // level-1 voxel 48
  EXPECT_EQ(l.stored_index(ivec3(1, 2, 3)), std::uint32_t((3 * 34 + 2) * 34 + 1));
}

}  // namespace
}  // namespace sl
