// The k-d split of the distributed renderer (DESIGN.md "Beyond one machine") and the sample clip it gives each rank
// (core/cast/sample_clip.h): every sample of the global per-ray grid belongs to exactly one region, the
// clipped index range is exactly the samples whose positions lie in the region, and the regions'
// order meets each ray's samples front to back.
#include "core/frame/kd_regions.h"

#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include <algorithm>
#include <vector>

#include "core/cast/raycast.h"

namespace sl {
namespace {

vec3 sample_pos(const Ray& r, float t_entry, float dt, int k) { return r.at(t_entry + float(k) * dt); }

WorkGrid random_grid() {
  const ivec3 dims(*rc::gen::inRange(1, 200), *rc::gen::inRange(1, 200), *rc::gen::inRange(1, 200));
  const vec3 spacing(*rc::gen::element(1.0f, 0.5f, 2.0f), 1.0f, *rc::gen::element(1.0f, 0.75f));
  WorkGrid g = make_work_grid(dims, spacing, *rc::gen::element(8, 16, 32));
  const bool sparse = *rc::gen::arbitrary<bool>();
  for (double& w : g.work) w = sparse && *rc::gen::inRange(0, 4) != 0 ? 0.0 : double(*rc::gen::inRange(0, 100));
  return g;
}

// A ray at the volume from outside or inside it, axis-aligned directions included.
Ray random_ray(const WorkGrid& g) {
  const vec3 ext = vec3(g.dims) * g.spacing;
  auto point = [&](int lo, int hi) {
    vec3 p;
    for (int a = 0; a < 3; ++a) p[a] = float(*rc::gen::inRange(lo, hi)) / 100.0f * ext[a];
    return p;
  };
  Ray r;
  r.origin = point(-50, 151);
  const vec3 target = point(1, 100);
  for (int a = 0; a < 3; ++a) {
    if (*rc::gen::inRange(0, 4) == 0) r.origin[a] = target[a];  // parallel to the planes of axis a
  }
  vec3 d = target - r.origin;
  if (d == vec3(0.0f)) d = vec3(0.0f, 0.0f, 1.0f);
  r.dir = glm::normalize(d);
  return r;
}

TEST(KdRegions, SplitsBalanceTheWorkOnCellBoundaries) {
  WorkGrid g = make_work_grid(ivec3(256, 32, 20), vec3(1.0f), 32);  // 8 x 1 x 1 cells
  ASSERT_EQ(g.cells, ivec3(8, 1, 1));
  g.work[g.index(ivec3(0, 0, 0))] = 4.0;
  g.work[g.index(ivec3(7, 0, 0))] = 12.0;
  const KdSplit s = split_regions(g, 2);
  ASSERT_EQ(s.regions.size(), 2u);
  EXPECT_EQ(s.nodes.size(), 1u);
  EXPECT_EQ(s.nodes[0].axis, 0);
  // All the work sits in cells 0 and 7: any boundary between them balances it as well as possible
  // (4 vs 12); the tie goes to the boundary nearest the middle.
  EXPECT_EQ(s.regions[0].hi.x, 4);
  EXPECT_EQ(s.regions[1].lo.x, 4);
  EXPECT_DOUBLE_EQ(s.regions[0].work, 4.0);
  EXPECT_DOUBLE_EQ(s.regions[1].work, 12.0);
  EXPECT_DOUBLE_EQ(s.max_over_mean_work(), 1.5);
  EXPECT_EQ(s.regions[0].box.hi.x, 128.0f);
  EXPECT_EQ(s.regions[0].clip.lo.x, -INFINITY);
  EXPECT_EQ(s.regions[0].clip.hi.x, 128.0f);
  EXPECT_EQ(s.regions[1].clip.hi.x, INFINITY);
}

TEST(KdRegions, ThreeRanksSplitOneAgainstTwo) {
  WorkGrid g = make_work_grid(ivec3(96, 96, 32), vec3(1.0f), 32);  // 3 x 3 x 1, uniform work
  std::fill(g.work.begin(), g.work.end(), 1.0);
  const KdSplit s = split_regions(g, 3);
  EXPECT_DOUBLE_EQ(s.regions[0].work, 3.0);
  EXPECT_DOUBLE_EQ(s.regions[1].work + s.regions[2].work, 6.0);
  EXPECT_DOUBLE_EQ(s.max_over_mean_work(), 1.0);
}

TEST(KdRegions, MoreRanksThanCellsLeavesEmptyRegionsThatOwnNoSample) {
  const WorkGrid g = make_work_grid(ivec3(20, 20, 20), vec3(1.0f), 32);  // one cell
  const KdSplit s = split_regions(g, 3);
  int empty = 0;
  for (const KdRegion& r : s.regions) empty += r.empty() ? 1 : 0;
  EXPECT_EQ(empty, 2);
  for (const KdRegion& r : s.regions) {
    if (r.empty()) EXPECT_FALSE(r.clip.contains(vec3(10.0f)));
    else EXPECT_TRUE(r.clip.contains(vec3(10.0f)) && r.clip.contains(vec3(-5.0f)) && r.clip.contains(vec3(99.0f)));
  }
  EXPECT_EQ(s.order(ViewPoint{}).size(), 3u);
}

TEST(SampleClip, OffKeepsEveryIndex) {
  Ray r;
  r.dir = glm::normalize(vec3(1.0f, 2.0f, 3.0f));
  int k0 = 3, k1 = 17;
  clip_samples(SampleClip{}, r, 0.25f, 0.5f, 2.0f, k0, k1);
  EXPECT_EQ(k0, 3);
  EXPECT_EQ(k1, 17);
}

// The union of the clipped sample sets over any k-d split is the unclipped set, each sample in
// exactly one region, and each region's range is exactly its samples (positions as the caster
// computes them); and the regions, in the split's order for the ray's eye, take the samples front
// to back.
RC_GTEST_PROP(SampleClipProperty, KdSplitPartitionsEveryRaysSamples, ()) {
  const WorkGrid g = random_grid();
  const int ranks = *rc::gen::inRange(1, 9);
  const KdSplit s = split_regions(g, ranks);
  const Ray ray = random_ray(g);
  const Box3 vbox{vec3(0.0f), vec3(g.dims) * g.spacing};
  const Interval iv = intersect(ray, vbox);
  const float t_entry = iv.t0 > 0.0f ? iv.t0 : 0.0f;
  RC_PRE(iv.t1 > t_entry);
  const float dt = *rc::gen::element(0.5f, 0.25f, 1.0f, 0.37f), inv_dt = 1.0f / dt;
  const int k_end = sample_index(iv.t1, t_entry, inv_dt);
  std::vector<int> owner(std::size_t(k_end), -1);
  for (int r = 0; r < ranks; ++r) {
    int k0 = 0, k1 = k_end;
    clip_samples(s.regions[std::size_t(r)].clip, ray, t_entry, dt, inv_dt, k0, k1);
    for (int k = 0; k < k_end; ++k) {
      const bool in_range = k >= k0 && k < k1;
      RC_ASSERT(in_range == s.regions[std::size_t(r)].clip.contains(sample_pos(ray, t_entry, dt, k)));
      if (in_range) {
        RC_ASSERT(owner[std::size_t(k)] == -1);
        owner[std::size_t(k)] = r;
      }
    }
  }
  for (int k = 0; k < k_end; ++k) RC_ASSERT(owner[std::size_t(k)] >= 0);
  // Front to back: along the ray, the owners' positions in the order never decrease.
  ViewPoint v;
  v.eye = ray.origin;
  const std::vector<int> order = s.order(v);
  RC_ASSERT(int(order.size()) == ranks);
  std::vector<int> pos(static_cast<std::size_t>(ranks), 0);
  for (int i = 0; i < ranks; ++i) pos[std::size_t(order[std::size_t(i)])] = i;
  for (int k = 1; k < k_end; ++k) {
    RC_ASSERT(pos[std::size_t(owner[std::size_t(k - 1)])] <= pos[std::size_t(owner[std::size_t(k)])]);
  }
}

// Orthographic: the order follows the view direction for parallel rays from anywhere.
RC_GTEST_PROP(SampleClipProperty, OrthographicOrderFollowsTheViewDirection, ()) {
  const WorkGrid g = random_grid();
  const int ranks = *rc::gen::inRange(2, 9);
  const KdSplit s = split_regions(g, ranks);
  const Ray ray = random_ray(g);
  ViewPoint v;
  v.orthographic = true;
  v.forward = ray.dir;
  v.eye = vec3(1e6f);  // ignored for orthographic views
  const std::vector<int> order = s.order(v);
  std::vector<int> pos(static_cast<std::size_t>(ranks), 0);
  for (int i = 0; i < ranks; ++i) pos[std::size_t(order[std::size_t(i)])] = i;
  const float dt = 0.5f;
  const Box3 vbox{vec3(0.0f), vec3(g.dims) * g.spacing};
  const Interval iv = intersect(ray, vbox);
  const float t_entry = iv.t0 > 0.0f ? iv.t0 : 0.0f;
  RC_PRE(iv.t1 > t_entry);
  const int k_end = sample_index(iv.t1, t_entry, 1.0f / dt);
  int last = -1;
  for (int k = 0; k < k_end; ++k) {
    const vec3 p = sample_pos(ray, t_entry, dt, k);
    int owner = -1;
    for (int r = 0; r < ranks; ++r) owner = s.regions[std::size_t(r)].clip.contains(p) ? r : owner;
    RC_ASSERT(owner >= 0);
    RC_ASSERT(pos[std::size_t(owner)] >= last);
    last = pos[std::size_t(owner)];
  }
}

}  // namespace
}  // namespace sl
