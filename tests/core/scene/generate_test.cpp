#include "core/scene/generate.h"

#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

#include "core/util/error.h"

namespace sl {
namespace {

bool same_bytes(const Volume& a, const Volume& b) {
  return a.dims() == b.dims() && a.type() == b.type() && a.desc().byte_size() == b.desc().byte_size() &&
         std::memcmp(a.data(), b.data(), a.desc().byte_size()) == 0;
}

bool same(const GeneratedVolume& a, const GeneratedVolume& b) {
  return a.label_count == b.label_count && same_bytes(a.intensity, b.intensity) &&
         a.labels.empty() == b.labels.empty() && (a.labels.empty() || same_bytes(a.labels, b.labels));
}

GeneratedVolume generate_with_threads(int threads, const std::string& kind, ivec3 dims, std::uint32_t seed) {
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, std::size_t(threads));
  return generate_volume(kind, dims, seed);
}

TEST(Generate, UnknownKindAndBadDims) {
  try {
    generate_volume("cubes", {8, 8, 8});
    ADD_FAILURE() << "no throw";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "gen: unknown kind 'cubes' (expected neurites, blobs, organs or sphere)");
  }
  for (const ivec3 dims : {ivec3(0, 8, 8), ivec3(8, -1, 8), ivec3(8, 8, 0)}) {
    for (const char* kind : {"neurites", "blobs", "organs", "sphere"}) {
      EXPECT_THROW(generate_volume(kind, dims), InputError) << kind;
    }
  }
  EXPECT_THROW(generate_volume("sphere", {1 << 30, 1 << 30, 1 << 30}), InputError);  // too large, no crash
}

TEST(Generate, DeterministicForSeedAndThreadCount) {
  const ivec3 dims(61, 47, 53);
  for (const char* kind : {"neurites", "blobs", "organs", "sphere"}) {
    SCOPED_TRACE(kind);
    const GeneratedVolume one = generate_with_threads(1, kind, dims, 7);
    const GeneratedVolume two = generate_with_threads(2, kind, dims, 7);
    const GeneratedVolume many = generate_with_threads(8, kind, dims, 7);  // oversubscribed schedule
    const GeneratedVolume again = generate_volume(kind, dims, 7);
    EXPECT_TRUE(same(one, two));
    EXPECT_TRUE(same(one, many));
    EXPECT_TRUE(same(one, again));
    if (std::string(kind) != "sphere") {
      EXPECT_FALSE(same(one, generate_volume(kind, dims, 8)));
    }
  }
}

TEST(Generate, NeuritesLookLikeSegmentedTubes) {
  const ivec3 dims(128, 96, 80);
  const GeneratedVolume g = generate_volume("neurites", dims, 1);
  ASSERT_EQ(g.intensity.dims(), dims);
  ASSERT_EQ(g.intensity.type(), VoxelType::U8);
  ASSERT_EQ(g.labels.dims(), dims);
  ASSERT_EQ(g.labels.type(), VoxelType::U16);
  EXPECT_GT(g.label_count, 20u);

  const auto* in = g.intensity.as<std::uint8_t>();
  const auto* lab = g.labels.as<std::uint16_t>();
  const std::size_t n = g.intensity.desc().voxel_count();
  std::size_t nonzero = 0, labelled = 0, partial = 0;
  std::vector<ivec3> lo(g.label_count + 1, dims), hi(g.label_count + 1, ivec3(-1));
  for (std::size_t i = 0; i < n; ++i) {
    nonzero += in[i] > 0;
    partial += in[i] > 0 && in[i] < 60;  // the smooth fringe outside the core
    if (lab[i] == 0) {
      EXPECT_LT(in[i], 128) << "bright voxel without a label at " << i;
      continue;
    }
    ++labelled;
    ASSERT_LE(lab[i], g.label_count);
    EXPECT_GE(in[i], 60) << "labelled voxel darker than half the dimmest tube at " << i;
    const ivec3 p(int(i % std::size_t(dims.x)), int(i / std::size_t(dims.x) % std::size_t(dims.y)),
                  int(i / (std::size_t(dims.x) * std::size_t(dims.y))));
    lo[lab[i]] = glm::min(lo[lab[i]], p);
    hi[lab[i]] = glm::max(hi[lab[i]], p);
  }
  const double occupancy = double(nonzero) / double(n);
  EXPECT_GE(occupancy, 0.01);
  EXPECT_LE(occupancy, 0.03);
  EXPECT_GT(double(labelled) / double(nonzero), 0.4);
  EXPECT_GT(partial, nonzero / 10);  // a profile, not a binary mask

  std::size_t present = 0, crossing = 0;
  for (std::uint32_t id = 1; id <= g.label_count; ++id) {
    if (hi[id].x < 0) continue;
    ++present;
    const ivec3 span = hi[id] - lo[id] + 1;
    crossing += span.x == dims.x || span.y == dims.y || span.z == dims.z;
  }
  EXPECT_GE(present, g.label_count * 9 / 10);  // nearly every tube visible somewhere
  EXPECT_GE(crossing, 1u);                     // some neurites run from one face to the opposite
}

TEST(Generate, NeuriteTubeCountGrowsWithVolume) {
  const auto small = generate_volume("neurites", {48, 48, 48}, 3);
  const auto large = generate_volume("neurites", {96, 96, 96}, 3);
  EXPECT_GT(large.label_count, 3 * small.label_count);
}

TEST(Generate, BlobsAreDenseAndLabelledByDominantGaussian) {
  const ivec3 dims(96, 80, 64);
  const GeneratedVolume g = generate_volume("blobs", dims, 5);
  ASSERT_EQ(g.intensity.type(), VoxelType::U8);
  ASSERT_EQ(g.labels.type(), VoxelType::U16);
  const auto* in = g.intensity.as<std::uint8_t>();
  const auto* lab = g.labels.as<std::uint16_t>();
  const std::size_t n = g.intensity.desc().voxel_count();
  std::size_t nonzero = 0, labelled = 0;
  for (std::size_t i = 0; i < n; ++i) {
    nonzero += in[i] > 0;
    if (lab[i]) {
      ++labelled;
      ASSERT_LE(lab[i], g.label_count);
      EXPECT_GE(in[i], 26);  // the dominant Gaussian alone exceeds 0.1 of full scale
    }
  }
  EXPECT_GE(double(nonzero) / double(n), 0.2);
  EXPECT_LE(double(nonzero) / double(n), 0.4);
  EXPECT_GT(labelled, nonzero / 5);
}

TEST(Generate, OrgansAreAFewLargeSegmentsFillingMostOfTheVolume) {
  const ivec3 dims(96, 80, 72);
  const GeneratedVolume g = generate_volume("organs", dims, 2);
  ASSERT_EQ(g.label_count, 4u);
  const auto* in = g.intensity.as<std::uint8_t>();
  const auto* lab = g.labels.as<std::uint16_t>();
  const std::size_t n = g.intensity.desc().voxel_count();
  std::size_t count[5] = {};
  for (std::size_t i = 0; i < n; ++i) {
    ASSERT_LE(lab[i], 4u);
    ++count[lab[i]];
    ASSERT_EQ(in[i] == 0, lab[i] == 0) << i;  // every body voxel is bright, the outside is 0
  }
  const double occupancy = 1.0 - double(count[0]) / double(n);
  EXPECT_NEAR(occupancy, 0.74, 0.04);
  for (int id = 1; id <= 4; ++id) EXPECT_GT(count[id], 0u) << id;
  EXPECT_LT(double(count[4]) / double(n), 0.01);  // the heart: a small segment for the sparse setting
  EXPECT_GT(count[2], count[1]);                  // the body is the largest
}

TEST(Generate, SphereIsTheDistanceFromTheCentre) {
  const ivec3 dims(64, 48, 33);
  const GeneratedVolume g = generate_volume("sphere", dims);
  ASSERT_EQ(g.intensity.type(), VoxelType::F32);
  EXPECT_TRUE(g.labels.empty());
  EXPECT_EQ(g.label_count, 0u);
  // Centre (32, 24, 16.5); voxel centres at i + 0.5.
  EXPECT_FLOAT_EQ(g.intensity.value(32, 24, 16), std::sqrt(0.25f + 0.25f + 0.0f));
  EXPECT_FLOAT_EQ(g.intensity.value(42, 24, 16), std::sqrt(10.5f * 10.5f + 0.25f));
  EXPECT_FLOAT_EQ(g.intensity.value(0, 0, 0), float(std::sqrt(31.5 * 31.5 + 23.5 * 23.5 + 16.0 * 16.0)));
  for (int x = 0; x < dims.x; ++x) {  // mirror symmetric about the centre
    EXPECT_EQ(g.intensity.value(x, 3, 7), g.intensity.value(dims.x - 1 - x, dims.y - 1 - 3, dims.z - 1 - 7));
  }
}

TEST(Generate, OddAndTinyDims) {
  for (const ivec3 dims : {ivec3(1, 1, 1), ivec3(3, 5, 7), ivec3(200, 7, 3), ivec3(2, 90, 2)}) {
    for (const char* kind : {"neurites", "blobs", "organs", "sphere"}) {
      const GeneratedVolume g = generate_volume(kind, dims, 11);
      EXPECT_EQ(g.intensity.dims(), dims) << kind;
      EXPECT_EQ(g.labels.empty(), std::string(kind) == "sphere") << kind;
    }
  }
}

// For any size and seed, the labels and the intensity tell the same story.
RC_GTEST_PROP(GenerateProperty, NeuriteLabelsAgreeWithIntensity, ()) {
  const ivec3 dims(*rc::gen::inRange(1, 40), *rc::gen::inRange(1, 40), *rc::gen::inRange(1, 40));
  const auto seed = *rc::gen::arbitrary<std::uint32_t>();
  const GeneratedVolume g = generate_volume("neurites", dims, seed);
  const auto* in = g.intensity.as<std::uint8_t>();
  const auto* lab = g.labels.as<std::uint16_t>();
  for (std::size_t i = 0; i < g.intensity.desc().voxel_count(); ++i) {
    RC_ASSERT(lab[i] <= g.label_count);
    if (lab[i]) RC_ASSERT(in[i] >= 60);
    if (in[i] >= 128) RC_ASSERT(lab[i] != 0);
  }
}

}  // namespace
}  // namespace sl
