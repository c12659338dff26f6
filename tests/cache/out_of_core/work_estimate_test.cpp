// The distributed renderer's work estimate (cache/out_of_core/work_estimate.h): non-empty culling blocks per
// coarse brick under the transfer function, summed over the ranks' shares.
#include "cache/out_of_core/work_estimate.h"

#include <gtest/gtest.h>

#include <memory>

namespace sl {
namespace {

// 128 x 64 x 64 u8, zero except a 20³ cube of 200 at voxels [70, 90)³ along x, [10, 30) in y and z.
std::shared_ptr<MemoryVolumeSource> cube_source() {
  auto v = std::make_shared<Volume>(VolumeDesc{ivec3(128, 64, 64), vec3(1.0f), VoxelType::U8});
  std::uint8_t* p = v->as<std::uint8_t>();
  for (int z = 10; z < 30; ++z)
    for (int y = 10; y < 30; ++y)
      for (int x = 70; x < 90; ++x) p[(std::size_t(z) * 64 + std::size_t(y)) * 128 + std::size_t(x)] = 200;
  return std::make_shared<MemoryVolumeSource>(v, nullptr, "cube");
}

TEST(WorkEstimate, CountsTheNonEmptyCullingBlocksPerBrick) {
  const auto src = cube_source();
  const BrickLayout layout = BrickLayout::make(src->desc(), 32);
  EXPECT_EQ(work_level(layout, 4), 0);  // 4 x 2 x 2 bricks
  EXPECT_EQ(work_level(layout, 2), 1);
  const TransferFunction tf({{0.0f, vec4(0.0f)}, {100.0f, vec4(0.0f)}, {255.0f, vec4(1.0f)}});
  CullParams cull;
  cull.tf = &tf;
  const WorkGrid g = estimate_work(*src, layout, 0, 16, cull);
  EXPECT_EQ(g.cells, ivec3(4, 2, 2));
  EXPECT_EQ(g.cell, 32);
  // The cube (dilated by one voxel) touches 16³ blocks x 4..5, y and z 0..1: 2 x 2 x 2 = 8 blocks,
  // all in brick (2, 0, 0).
  double total = 0.0;
  for (double w : g.work) total += w;
  EXPECT_DOUBLE_EQ(total, 8.0);
  EXPECT_DOUBLE_EQ(g.work[g.index(ivec3(2, 0, 0))], 8.0);
  // Without an opacity test every block counts: (128/16) x (64/16) x (64/16).
  CullParams all;
  const WorkGrid a = estimate_work(*src, layout, 0, 16, all);
  total = 0.0;
  for (double w : a.work) total += w;
  EXPECT_DOUBLE_EQ(total, 128.0);
}

TEST(WorkEstimate, SharesSumToTheWholeEstimate) {
  const auto src = cube_source();
  const BrickLayout layout = BrickLayout::make(src->desc(), 16);
  const TransferFunction tf({{0.0f, vec4(0.0f)}, {100.0f, vec4(0.0f)}, {255.0f, vec4(1.0f)}});
  CullParams cull;
  cull.tf = &tf;
  const WorkGrid whole = estimate_work(*src, layout, 0, 8, cull);
  WorkGrid sum = make_work_grid(whole.dims, whole.spacing, whole.cell);
  for (int part = 0; part < 3; ++part) {
    const WorkGrid g = estimate_work(*src, layout, 0, 8, cull, part, 3);
    for (std::size_t i = 0; i < g.work.size(); ++i) {
      if (int(i % 3) != part) {
        EXPECT_EQ(g.work[i], 0.0);
      }
      sum.work[i] += g.work[i];
    }
  }
  EXPECT_EQ(sum.work, whole.work);
  // The split keeps every cell's work in exactly one region.
  const KdSplit s = split_regions(whole, 2);
  double t = 0.0;
  for (double w : whole.work) t += w;
  EXPECT_GT(t, 0.0);
  EXPECT_DOUBLE_EQ(s.regions[0].work + s.regions[1].work, t);
}

}  // namespace
}  // namespace sl
