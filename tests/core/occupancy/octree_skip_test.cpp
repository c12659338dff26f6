// The octree baseline (DESIGN.md "Ray casting"): min/max structure and the kd-restart step (Foley & Sugerman).
#include "core/occupancy/octree_skip.h"

#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include <algorithm>
#include <vector>

namespace sl {
namespace {

using C = OccupancyClass;

TEST(SkipOctree, InnerNodesAreNonEmptyIfAnyChildIsAndEmptySubtreesCollapse) {
  const BlockGrid g = make_block_grid(ivec3(16), vec3(1.0f), 4);  // 4^3 blocks, 2 levels
  std::vector<C> classes(g.block_count(), C::Empty);
  classes[g.block_index(ivec3(3, 3, 3))] = C::Unknown;  // counts as NON_EMPTY
  const SkipOctree t(g, classes);
  ASSERT_EQ(t.nodes().size(), 1u + 8u + 8u);  // only the path to the one non-empty block is split
  EXPECT_EQ(C(t.nodes()[0].cls), C::NonEmpty);
  EXPECT_EQ(C(t.nodes()[8].cls), C::NonEmpty);  // child 7 of the root
  EXPECT_EQ(C(t.nodes()[1].cls), C::Empty);
  EXPECT_EQ(t.nodes()[1].children, SkipOctree::kNone);
  EXPECT_EQ(C(t.nodes()[9 + 7].cls), C::NonEmpty);
  const SkipOctree empty(g, std::vector<C>(g.block_count(), C::Empty));
  EXPECT_EQ(empty.nodes().size(), 1u);
}

TEST(SkipOctree, StepOnASplitPlaneMovesForward) {
  const BlockGrid g = make_block_grid(ivec3(16), vec3(1.0f), 8);  // 2^3 blocks
  std::vector<C> classes(g.block_count(), C::Empty);
  classes[g.block_index(ivec3(1, 0, 0))] = C::NonEmpty;
  const SkipOctree t(g, classes);
  const SkipOctreeView v = t.view();
  const Ray right{vec3(-1.0f, 4.0f, 4.0f), vec3(1.0f, 0.0f, 0.0f)};
  KdRestartStep s = v.step(right, 1.0f, 17.0f);  // enters at x = 0
  EXPECT_EQ(s.cls, C::Empty);
  EXPECT_EQ(s.t1, 9.0f);                         // the split plane x = 8
  EXPECT_EQ(s.nodes_visited, 2u);
  s = v.step(right, 9.0f, 17.0f);                // exactly on the plane: the direction decides
  EXPECT_EQ(s.cls, C::NonEmpty);
  EXPECT_EQ(s.t1, 17.0f);
  const Ray left{vec3(17.0f, 4.0f, 4.0f), vec3(-1.0f, 0.0f, 0.0f)};
  s = v.step(left, 9.0f, 17.0f);
  EXPECT_EQ(s.cls, C::Empty);
  EXPECT_EQ(s.t1, 17.0f);
}

struct Rng {
  std::uint64_t s;
  std::uint64_t next() {
    s = s * 6364136223846793005ull + 1442695040888963407ull;
    return s >> 11;
  }
  float uniform(float a, float b) { return a + (b - a) * float(double(next()) * 0x1.0p-53); }
};

RC_GTEST_PROP(SkipOctreeProperty, KdRestartVisitsTheLeavesInOrder, (std::uint64_t seed, bool inside)) {
  Rng rng{seed};
  const int block = 4;
  const ivec3 dims(int(rng.uniform(5, 64)), int(rng.uniform(5, 64)), int(rng.uniform(5, 64)));
  const vec3 spacing(rng.uniform(0.5f, 2.0f), rng.uniform(0.5f, 2.0f), rng.uniform(0.5f, 2.0f));
  const BlockGrid g = make_block_grid(dims, spacing, block);
  // Clustered classes: a few non-empty / unknown balls in empty space.
  std::vector<C> classes(g.block_count(), C::Empty);
  for (int ball = 0; ball < 3; ++ball) {
    const vec3 c(rng.uniform(0, float(g.blocks.x)), rng.uniform(0, float(g.blocks.y)), rng.uniform(0, float(g.blocks.z)));
    const float r = rng.uniform(0.5f, 4.0f);
    for (std::size_t i = 0; i < classes.size(); ++i) {
      if (glm::length(vec3(g.block_coord(i)) + 0.5f - c) < r) classes[i] = ball == 0 ? C::Unknown : C::NonEmpty;
    }
  }
  const SkipOctree tree(g, classes);
  const SkipOctreeView view = tree.view();
  const std::vector<SkipOctree::Leaf> leaves = tree.leaves();
  const Box3 vb = g.volume_box();
  const float scale = glm::length(vb.hi);
  for (int k = 0; k < 100; ++k) {
    vec3 eye, target(rng.uniform(0, vb.hi.x), rng.uniform(0, vb.hi.y), rng.uniform(0, vb.hi.z));
    if (rng.next() % 3 == 0) {  // through block corners and edges
      for (int a = 0; a < 3; ++a) target[a] = g.plane(a, std::min(dims[a], block * int(rng.next() % (g.blocks[a] + 1))));
    }
    if (inside) {
      eye = vec3(rng.uniform(0.05f, 0.95f), rng.uniform(0.05f, 0.95f), rng.uniform(0.05f, 0.95f)) * vb.hi;
    } else {
      do {
        eye = vec3(rng.uniform(-1.5f, 2.5f), rng.uniform(-1.5f, 2.5f), rng.uniform(-1.5f, 2.5f)) * vb.hi;
      } while (vb.contains(eye));
    }
    if (glm::length(target - eye) == 0.0f) continue;
    const Ray ray{eye, glm::normalize(target - eye)};
    const Interval iv = intersect(ray, vb);
    const float t_entry = std::max(iv.t0, 0.0f);
    if (!(iv.t1 > t_entry)) continue;
    // kd-restart walk.
    std::vector<KdRestartStep> steps;
    for (float t = t_entry; t < iv.t1;) {
      const KdRestartStep s = view.step(ray, t, iv.t1);
      RC_ASSERT(s.t1 > t);  // progress
      RC_ASSERT(s.nodes_visited >= 1u && s.nodes_visited <= std::uint32_t(tree.levels() + 1));
      steps.push_back(s);
      t = s.t1;
      RC_ASSERT(steps.size() < 100000u);
    }
    // Brute force: the leaves the ray crosses, front to back.
    std::vector<KdRestartStep> want;
    for (const SkipOctree::Leaf& l : leaves) {
      const Interval li = intersect(ray, l.box);
      if (li.empty() || !(li.t1 > t_entry)) continue;
      want.push_back({std::max(li.t0, t_entry), li.t1, l.cls, 0});
    }
    std::sort(want.begin(), want.end(), [](const auto& a, const auto& b) { return a.t0 < b.t0; });
    // The same leaves in the same order (up to rounding slivers where a ray passes a corner).
    const float tol = 1e-5f * scale;
    auto drop_slivers = [&](std::vector<KdRestartStep> v) {
      v.erase(std::remove_if(v.begin(), v.end(), [&](const KdRestartStep& s) { return s.t1 - s.t0 <= tol; }), v.end());
      return v;
    };
    const auto a = drop_slivers(steps), b = drop_slivers(want);
    RC_ASSERT(a.size() == b.size());
    for (std::size_t i = 0; i < a.size(); ++i) {
      RC_ASSERT(a[i].cls == b[i].cls);
      RC_ASSERT(std::abs(a[i].t0 - b[i].t0) <= tol && std::abs(a[i].t1 - b[i].t1) <= tol);
    }
    // Non-empty intervals cover exactly the non-empty blocks along the ray.
    auto merged_nonempty = [&](const std::vector<std::pair<Interval, C>>& spans) {
      std::vector<Interval> out;
      for (const auto& [i, c] : spans) {
        if (c == C::Empty || !(i.t1 - i.t0 > tol)) continue;
        if (!out.empty() && i.t0 <= out.back().t1 + tol) {
          out.back().t1 = std::max(out.back().t1, i.t1);
        } else {
          out.push_back(i);
        }
      }
      return out;
    };
    std::vector<std::pair<Interval, C>> from_steps, from_blocks;
    for (const auto& s : steps) from_steps.push_back({Interval{s.t0, s.t1}, s.cls});
    for (std::size_t i = 0; i < classes.size(); ++i) {
      const Interval bi = intersect(ray, g.block_box(g.block_coord(i)));
      if (bi.empty() || !(bi.t1 > t_entry)) continue;
      from_blocks.push_back({Interval{std::max(bi.t0, t_entry), bi.t1}, classes[i]});
    }
    std::sort(from_blocks.begin(), from_blocks.end(), [](const auto& x, const auto& y) { return x.first.t0 < y.first.t0; });
    const auto m1 = merged_nonempty(from_steps), m2 = merged_nonempty(from_blocks);
    RC_ASSERT(m1.size() == m2.size());
    for (std::size_t i = 0; i < m1.size(); ++i) {
      RC_ASSERT(std::abs(m1[i].t0 - m2[i].t0) <= tol && std::abs(m1[i].t1 - m2[i].t1) <= tol);
    }
  }
}

}  // namespace
}  // namespace sl
