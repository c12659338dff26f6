// Visibility order (paper §6.2, Alg. 3; seed 002): FRONT before and BACK after everything a box
// contains, and front to back along every ray from the eye (perspective) or along the view direction.
#include "core/lists/visibility_order.h"

#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include <algorithm>
#include <vector>

namespace sl {
namespace {

using C = OccupancyClass;

BlockGrid cube_grid(int levels, int block = 4) { return make_block_grid(ivec3(block << levels), vec3(1.0f), block); }

TEST(VisibilityOrder, OctantXorOrderVisitsTheEyesChildFirst) {
  const ViewPoint above{vec3(10.0f), vec3(0.0f), false};  // + side of every axis
  EXPECT_EQ(view_octant(above, vec3(0.0f)), 0u);
  EXPECT_EQ(view_octant(above, vec3(0.0f)) ^ kOctantOrder[0], 7u);  // nearest child: upper on all axes
  EXPECT_EQ(view_octant(above, vec3(0.0f)) ^ kOctantOrder[7], 0u);  // farthest last
  const ViewPoint mixed{vec3(-1.0f, 1.0f, -1.0f), vec3(0.0f), false};
  EXPECT_EQ(view_octant(mixed, vec3(0.0f)) ^ kOctantOrder[0], 2u);  // x lower, y upper, z lower
  // Seed 002's example: octant 110 gives children 1, 0, 3, 5, 2, 4, 7, 6.
  const std::uint32_t want[8] = {1, 0, 3, 5, 2, 4, 7, 6};
  for (int i = 0; i < 8; ++i) EXPECT_EQ(6u ^ kOctantOrder[i], want[i]);
  // Orthographic: the eye at infinity along -forward.
  const ViewPoint ortho{vec3(0.0f), glm::normalize(vec3(1.0f, -1.0f, 0.5f)), true};
  EXPECT_EQ(view_octant(ortho, vec3(123.0f)) ^ kOctantOrder[0], 2u);
}

TEST(VisibilityOrder, LeafEntriesAreAdjacentAndNonEmittersListNothing) {
  OccupancyTree t(cube_grid(1), C::Empty);
  const std::uint32_t c = t.refine(t.root());
  for (int k = 0; k < 8; ++k) t.set_leaf_class(c + k, k == 7 || k == 0 ? C::NonEmpty : C::Empty);
  t.propagate();
  const OccupancyGeometry g = build_occupancy_geometry(t);
  const auto order = build_visibility_order(t, g, ViewPoint{vec3(100.0f), vec3(0.0f), false});
  ASSERT_EQ(order.size(), 6u);
  const std::uint32_t b7 = g.node_box[c + 7], b0 = g.node_box[c + 0];
  EXPECT_EQ(order[0].box, 0u);
  EXPECT_EQ(order[0].face, Face::Front);
  EXPECT_EQ(order[1].box, b7);  // the child nearest the eye first
  EXPECT_EQ(order[1].face, Face::Front);
  EXPECT_EQ(order[2].box, b7);
  EXPECT_EQ(order[2].face, Face::Back);
  EXPECT_EQ(order[3].box, b0);
  EXPECT_EQ(order[5].box, 0u);
  EXPECT_EQ(order[5].face, Face::Back);
}

TEST(VisibilityOrder, StaleGeometryIsRejected) {
  OccupancyTree t(cube_grid(2), C::Unknown);
  const std::uint32_t c = t.refine(t.root());
  t.propagate();
  const OccupancyGeometry g = build_occupancy_geometry(t);
  const ViewPoint v{vec3(100.0f), vec3(0.0f), false};
  EXPECT_NO_THROW(build_visibility_order(t, g, v));
  t.touch(c, 5);  // usage stamps do not change occupancy
  EXPECT_NO_THROW(build_visibility_order(t, g, v));
  t.set_leaf_class(c + 3, C::Empty);
  EXPECT_THROW(build_visibility_order(t, g, v), std::logic_error);
}

bool is_ancestor(const OccupancyTree& t, std::uint32_t a, std::uint32_t n) {
  for (std::uint32_t i = t.node(n).parent; i != OccupancyTree::kNone; i = t.node(i).parent) {
    if (i == a) return true;
  }
  return false;
}

struct Rng {
  std::uint64_t s;
  float uniform(float a, float b) {
    s = s * 6364136223846793005ull + 1442695040888963407ull;
    return a + (b - a) * float(double(s >> 11) * 0x1.0p-53);
  }
};

RC_GTEST_PROP(VisibilityOrderProperty, NestedAndFrontToBack, (std::uint64_t seed, bool inside, bool ortho)) {
  const int levels = *rc::gen::inRange(1, 4);
  const OccupancyTree t = make_random_occupancy_tree(cube_grid(levels), seed, RandomTreeParams{levels, 0.7, 0.6});
  const OccupancyGeometry g = build_occupancy_geometry(t, *rc::gen::element<std::size_t>(0, 0, 7));
  Rng rng{seed};
  const vec3 ext = g.boxes[0].box.hi;
  vec3 eye(rng.uniform(-1.5f, 2.5f), rng.uniform(-1.5f, 2.5f), rng.uniform(-1.5f, 2.5f));
  if (inside) eye = vec3(rng.uniform(0.05f, 0.95f), rng.uniform(0.05f, 0.95f), rng.uniform(0.05f, 0.95f));
  eye *= ext;
  const vec3 fwd = glm::normalize(0.5f * ext - eye + vec3(0.01f, 0.02f, 0.03f));
  const auto order = build_visibility_order(t, g, ViewPoint{eye, fwd, ortho});

  // Each box twice, FRONT first; every FRONT precedes and every BACK follows its descendants' entries,
  // and non-descendants stay outside the pair (proper nesting).
  std::vector<int> front(g.boxes.size(), -1), back(g.boxes.size(), -1);
  for (int i = 0; i < int(order.size()); ++i) {
    std::vector<int>& slot = order[i].face == Face::Front ? front : back;
    RC_ASSERT(slot[order[i].box] == -1);
    slot[order[i].box] = i;
  }
  for (std::size_t b = 0; b < g.boxes.size(); ++b) {
    RC_ASSERT(front[b] >= 0 && back[b] > front[b]);
    if (effective_leaf(t, g, g.boxes[b].node)) RC_ASSERT(back[b] == front[b] + 1);
  }
  for (std::size_t a = 0; a < g.boxes.size(); ++a) {
    for (std::size_t b = 0; b < g.boxes.size(); ++b) {
      if (a == b) continue;
      const bool inner = front[a] < front[b] && front[b] < back[a];
      RC_ASSERT(inner == is_ancestor(t, g.boxes[a].node, g.boxes[b].node));
      if (inner) RC_ASSERT(back[b] < back[a]);
    }
  }
  // Front to back: along any ray, of two boxes with disjoint interiors the earlier-ordered one is met
  // first.
  for (int k = 0; k < 20; ++k) {
    const vec3 target(rng.uniform(0.0f, ext.x), rng.uniform(0.0f, ext.y), rng.uniform(0.0f, ext.z));
    Ray ray;
    if (ortho) {
      ray.dir = fwd;
      ray.origin = target - glm::dot(target - eye, fwd) * fwd;
    } else {
      ray.origin = eye;
      ray.dir = glm::normalize(target - eye);
    }
    const float tol = 1e-5f * glm::length(ext);
    for (std::size_t a = 0; a < g.boxes.size(); ++a) {
      for (std::size_t b = 0; b < g.boxes.size(); ++b) {
        if (front[a] >= front[b] || is_ancestor(t, g.boxes[a].node, g.boxes[b].node)) continue;
        const Interval ia = intersect(ray, g.boxes[a].box), ib = intersect(ray, g.boxes[b].box);
        if (ia.empty() || ib.empty() || !(ia.t1 > 0.0f) || !(ib.t1 > 0.0f)) continue;
        RC_ASSERT(std::max(ia.t0, 0.0f) <= std::max(ib.t0, 0.0f) + tol);
        RC_ASSERT(ia.t1 <= std::max(ib.t0, 0.0f) + tol);
      }
    }
  }
}

}  // namespace
}  // namespace sl
