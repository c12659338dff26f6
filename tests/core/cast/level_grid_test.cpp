// The level-adaptive sample grid (LodParams::grid_level): a sample at level l is taken only at every
// 2^(l - grid_level)-th grid index, with its opacity corrected for the longer step. Proven on a long
// ray through a dense volume whose level of detail climbs four levels along it: the samples taken
// are exactly the rule's, any partition of the ray into spans (as the skipping methods cut it) takes
// the same samples and composites the same colour bit for bit, and a homogeneous medium keeps its
// opacity (Beer–Lambert) within the few steps where the stride changes.
#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

#include "core/cast/raycast.h"
#include "core/scene/transfer_function.h"

namespace sl {
namespace {

constexpr ivec3 kDims(8, 8, 1024);

struct Medium {
  std::vector<std::uint8_t> voxels;
  TransferFunction tf;
  explicit Medium(std::uint8_t value = 100, float alpha = 0.001f)
      : voxels(std::size_t(kDims.x) * kDims.y * kDims.z, value),
        tf({TfPoint{0.0f, vec4(1.0f, 0.5f, 0.25f, alpha)}, TfPoint{255.0f, vec4(1.0f, 0.5f, 0.25f, alpha)}}) {}
};

// Along z from 100 voxels before the volume: the footprint ratio t * 0.02 is 2 at the entry (level
// 1, the grid's level) and 22.5 at the exit (level 4).
RayCaster<DenseSampler<std::uint8_t, std::uint16_t>> make_caster(const Medium& m, int grid_level) {
  RayCaster<DenseSampler<std::uint8_t, std::uint16_t>> c;
  c.p.mode = RenderMode::Dvr;
  c.p.dt = 0.5f;
  c.p.inv_dt = 2.0f;
  c.p.tf = m.tf.view(0.5f);
  c.p.simd = false;
  c.p.lod.levels = 6;
  c.p.lod.pixel_angle = 0.02f;
  c.p.lod.inv_voxel = 1.0f;
  c.p.lod.grid_level = grid_level;
  c.volume.volume = DenseGrid<std::uint8_t>{m.voxels.data(), kDims, vec3(1.0f)};
  return c;
}

const Ray kRay{vec3(4.0f, 4.0f, -100.0f), vec3(0.0f, 0.0f, 1.0f)};
constexpr float kEntry = 100.0f;
constexpr int kSamples = 2048;  // the volume's 1024 voxels at half a voxel

int expected_samples(const LodParams& lod, float dt) {
  int n = 0;
  for (int k = 0; k < kSamples; ++k) {
    const int s = lod.stride_log2(lod.level_at(kEntry + float(k) * dt));
    n += (k & ((1 << s) - 1)) == 0;
  }
  return n;
}

TEST(LevelAdaptiveGrid, TakesEachLevelsStrideThGridSample) {
  const Medium m;
  const auto c = make_caster(m, 1);
  EXPECT_EQ(c.p.lod.level_at(kEntry), 1);
  EXPECT_EQ(c.p.lod.level_at(kEntry + 1024.0f), 4);
  RayAccum acc;
  c.march(kRay, kEntry, 0, kSamples, acc);
  EXPECT_EQ(int(acc.samples), expected_samples(c.p.lod, c.p.dt));
  // Levels 1..4 at strides 1, 2, 4 and 8 over bands of 50, 100, 200 and 674 voxels.
  EXPECT_LT(acc.samples, std::uint32_t(kSamples / 3));

  const auto every = make_caster(m, -1);
  RayAccum all;
  every.march(kRay, kEntry, 0, kSamples, all);
  EXPECT_EQ(int(all.samples), kSamples);
  // The same medium: (1 - a)^n over the same length, whatever the steps; only where a stride
  // changes does a sample stand for a few steps more or less than it follows.
  EXPECT_NEAR(acc.alpha, all.alpha, 0.01f);
  EXPECT_NEAR(acc.color.x, all.color.x, 0.01f);
  EXPECT_GT(all.alpha, 0.3f);
}

TEST(LevelAdaptiveGrid, ConstantLevelAndSampledIsoTakeEverySample) {
  const Medium m;
  auto pinned = make_caster(m, 1);
  pinned.p.lod.pinned = 3;  // one level for every sample: nothing to thin
  RayAccum a;
  pinned.march(kRay, kEntry, 0, kSamples, a);
  EXPECT_EQ(int(a.samples), kSamples);
  auto iso = make_caster(m, 1);
  iso.p.mode = RenderMode::Iso;
  iso.p.iso_method = IsoMethod::Sampled;
  iso.p.iso = 200.0f;  // never crossed: every sample is taken
  RayAccum b;
  iso.march(kRay, kEntry, 0, kSamples, b);
  EXPECT_EQ(int(b.samples), kSamples);
}

// Any cut of the ray into consecutive spans takes the same samples and composites the same colour as
// one march over it (adjacent spans partition the thinned grid as they partition the grid).
RC_GTEST_PROP(LevelAdaptiveGrid, SpansPartitionTheThinnedGrid, ()) {
  const auto value = *rc::gen::inRange(1, 256);
  const Medium m(std::uint8_t(value), *rc::gen::element(0.001f, 0.01f, 0.2f));
  auto c = make_caster(m, *rc::gen::inRange(0, 3));
  c.p.mode = *rc::gen::element(RenderMode::Dvr, RenderMode::Mip);
  auto cuts = *rc::gen::container<std::vector<int>>(rc::gen::inRange(0, kSamples));
  cuts.push_back(0);
  cuts.push_back(kSamples);
  std::sort(cuts.begin(), cuts.end());
  RayAccum whole, pieces;
  c.march(kRay, kEntry, 0, kSamples, whole);
  for (std::size_t i = 0; i + 1 < cuts.size(); ++i) c.march(kRay, kEntry, cuts[i], cuts[i + 1], pieces);
  RC_ASSERT(whole.samples == pieces.samples);
  RC_ASSERT(int(whole.samples) == expected_samples(c.p.lod, c.p.dt));
  RC_ASSERT(std::memcmp(&whole.color, &pieces.color, sizeof(vec3)) == 0);
  RC_ASSERT(std::memcmp(&whole.alpha, &pieces.alpha, sizeof(float)) == 0);
  RC_ASSERT(whole.mip_max == pieces.mip_max);
}

// LodParams::level_at reads a level off the footprint ratio's exponent bits instead of calling
// log2f for every sample: the same level as floorf(log2f(ratio)) for every float from 2 to 2^17 (16
// levels, every one of its 2^23 mantissas per level, the windows next to the powers of two where
// the bits defer to log2f included), and an infinite ratio is the coarsest level.
TEST(LevelOfDetail, ExponentBitsGiveLog2fsLevelForEveryFloat) {
  std::uint64_t differing = 0;
  float first = 0.0f;
  for (std::uint32_t bits = 0x40000000u; bits < 0x48000000u; ++bits) {  // [2, 2^17)
    float x;
    std::memcpy(&x, &bits, sizeof x);
    if (LodParams::floor_log2(x) != int(floorf(log2f(x)))) {
      if (differing++ == 0) first = x;
    }
  }
  EXPECT_EQ(differing, 0u) << "first at " << first;
  LodParams lod;
  lod.levels = 9;
  lod.pixel_size = INFINITY;
  EXPECT_EQ(lod.level_at(1.0f), 8);
  lod.pixel_size = NAN;
  EXPECT_EQ(lod.level_at(1.0f), 0);
  lod.pixel_size = 0.0f;
  lod.pixel_angle = 0.5f;
  lod.inv_voxel = 1.0f;
  EXPECT_EQ(lod.level_at(3.999f), 0);
  EXPECT_EQ(lod.level_at(4.0f), 1);
  EXPECT_EQ(lod.level_at(16.0f), 3);
  EXPECT_EQ(lod.level_at(1e30f), 8);
}

}  // namespace
}  // namespace sl
