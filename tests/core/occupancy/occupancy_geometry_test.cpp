// Occupancy geometry (paper §6.1, Alg. 2): breadth-first emission where a node's class differs from
// its parent's, clipping to the volume, and the conservative box budget.
#include "core/occupancy/occupancy_geometry.h"

#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include <cstring>
#include <deque>
#include <vector>

namespace sl {
namespace {

using C = OccupancyClass;

BlockGrid cube_grid(int levels, int block = 4) { return make_block_grid(ivec3(block << levels), vec3(1.0f), block); }

TEST(OccupancyGeometry, RootAlwaysEmitsAndChildrenEmitOnAClassChange) {
  OccupancyTree t(cube_grid(1), C::Empty);
  const std::uint32_t c = t.refine(t.root());
  for (int k = 0; k < 8; ++k) t.set_leaf_class(c + k, k == 5 ? C::NonEmpty : (k == 6 ? C::Unknown : C::Empty));
  t.propagate();
  const OccupancyGeometry g = build_occupancy_geometry(t);
  ASSERT_EQ(g.boxes.size(), 3u);
  EXPECT_EQ(g.boxes[0].node, t.root());
  EXPECT_EQ(g.boxes[0].cls, C::Empty);
  EXPECT_EQ(g.boxes[0].parent_cls, C::Invalid);
  EXPECT_EQ(g.boxes[1].node, c + 5);  // fixed child order, not visibility order
  EXPECT_EQ(g.boxes[1].cls, C::NonEmpty);
  EXPECT_EQ(g.boxes[1].parent_cls, C::Empty);
  EXPECT_EQ(g.boxes[2].node, c + 6);
  EXPECT_EQ(g.boxes[2].box.lo, vec3(0.0f, 4.0f, 4.0f));
  EXPECT_EQ(g.boxes[2].box.hi, vec3(4.0f, 8.0f, 8.0f));
  EXPECT_EQ(g.node_box[c + 5], 1u);
  EXPECT_EQ(g.node_box[c + 0], OccupancyGeometry::kNoBox);
  EXPECT_FALSE(g.truncated);
}

TEST(OccupancyGeometry, NonPowerOfTwoBoxesAreClippedAndOutsideNodesDropped) {
  const BlockGrid grid = make_block_grid(ivec3(97, 131, 73), vec3(0.5f, 1.0f, 2.0f), 16);
  std::vector<C> classes(grid.block_count(), C::Empty);
  for (std::size_t i = 0; i < classes.size(); i += 3) classes[i] = C::NonEmpty;
  const OccupancyTree t = OccupancyTree::from_block_classes(grid, classes);
  const OccupancyGeometry g = build_occupancy_geometry(t);
  const Box3 vb = grid.volume_box();
  EXPECT_EQ(vb.hi, vec3(48.5f, 131.0f, 146.0f));
  ASSERT_FALSE(g.boxes.empty());
  EXPECT_EQ(g.boxes[0].box.lo, vb.lo);
  EXPECT_EQ(g.boxes[0].box.hi, vb.hi);
  bool some_clipped = false;
  for (const OccupancyBox& b : g.boxes) {
    for (int a = 0; a < 3; ++a) {
      EXPECT_GE(b.box.lo[a], vb.lo[a]);
      EXPECT_LE(b.box.hi[a], vb.hi[a]);
      EXPECT_LT(b.box.lo[a], b.box.hi[a]);  // never degenerate (wholly outside nodes are dropped)
    }
    EXPECT_FALSE(t.outside(b.node));
    const Box3 full = t.node_box(b.node);
    some_clipped = some_clipped || full.hi != b.box.hi;
  }
  EXPECT_TRUE(some_clipped);
  // Leaves tile the volume exactly.
  double vol = 0.0;
  for (const OccupancyBox& b : leaf_boxes(t)) {
    const vec3 e = b.box.hi - b.box.lo;
    vol += double(e.x) * e.y * e.z;
  }
  EXPECT_NEAR(vol, 48.5 * 131.0 * 146.0, 1e-6 * vol);
}

TEST(OccupancyGeometry, BudgetCutsConservatively) {
  OccupancyTree t(cube_grid(2), C::Empty);
  const std::uint32_t c = t.refine(t.root());
  for (int k = 0; k < 8; ++k) {
    const std::uint32_t d = t.refine(c + k);
    for (int j = 0; j < 8; ++j) t.set_leaf_class(d + j, j == k ? C::NonEmpty : C::Empty);  // 1 of 8 non-empty
  }
  t.propagate();
  const OccupancyGeometry full = build_occupancy_geometry(t);
  EXPECT_EQ(full.boxes.size(), 1u + 8u);  // EMPTY root, 8 NON_EMPTY blocks
  const OccupancyGeometry cut = build_occupancy_geometry(t, 5);
  EXPECT_TRUE(cut.truncated);
  ASSERT_EQ(cut.boxes.size(), 1u);  // the cut at depth 0: one conservative box
  EXPECT_EQ(cut.boxes[0].cls, C::NonEmpty);
  EXPECT_EQ(effective_class(t, cut, t.root()), C::NonEmpty);
  EXPECT_TRUE(effective_leaf(t, cut, t.root()));
  const OccupancyGeometry enough = build_occupancy_geometry(t, 9);
  EXPECT_FALSE(enough.truncated);
  EXPECT_EQ(enough.boxes.size(), 9u);
}

RC_GTEST_PROP(OccupancyGeometryProperty, Alg2EmissionAndBudget, (std::uint64_t seed)) {
  const int levels = *rc::gen::inRange(1, 5);
  const OccupancyTree t = make_random_occupancy_tree(cube_grid(levels), seed, RandomTreeParams{levels, 0.7, 0.6});
  const std::size_t budget = *rc::gen::inRange<std::size_t>(0, 60);
  const OccupancyGeometry g = build_occupancy_geometry(t, budget);
  if (budget > 0) RC_ASSERT(g.boxes.size() <= budget);
  // Breadth first: depth never decreases; a box is emitted exactly where the (effective) class of a
  // node differs from its parent's, down to the cut.
  for (std::size_t i = 1; i < g.boxes.size(); ++i) RC_ASSERT(g.boxes[i].depth >= g.boxes[i - 1].depth);
  std::deque<std::uint32_t> queue{t.root()};
  std::size_t emitted = 0;
  while (!queue.empty()) {
    const std::uint32_t n = queue.front();
    queue.pop_front();
    const std::uint32_t p = t.node(n).parent;
    const C pc = p == OccupancyTree::kNone ? C::Invalid : effective_class(t, g, p);
    const bool emits = effective_class(t, g, n) != pc;
    RC_ASSERT((g.node_box[n] != OccupancyGeometry::kNoBox) == emits);
    if (emits) {
      const OccupancyBox& b = g.boxes[g.node_box[n]];
      RC_ASSERT(g.node_box[n] == emitted);  // the same order as this queue
      RC_ASSERT(b.cls == effective_class(t, g, n) && b.parent_cls == pc && b.node == n);
      ++emitted;
    }
    if (!effective_leaf(t, g, n)) {
      for (int k = 0; k < 8; ++k) queue.push_back(t.child(n, k));
    }
  }
  RC_ASSERT(emitted == g.boxes.size());
  // A cut never turns a non-empty or unknown block EMPTY.
  for (const OccupancyBox& leaf : leaf_boxes(t, g.depth_limit)) {
    if (leaf.cls != C::Empty) continue;
    for (const OccupancyBox& fine : leaf_boxes(t)) {
      const vec3 c = 0.5f * (fine.box.lo + fine.box.hi);
      if (leaf.box.contains(c)) RC_ASSERT(fine.cls == C::Empty);
    }
  }
}

// flatten_sparse_subtrees: every effective leaf keeps its class (the class of the innermost box around
// it, as the lists read the nesting); a box is either the original box of its node or a sampled leaf
// directly inside EMPTY, in a subtree whose root was a sampled box inside EMPTY; breadth first; never
// more than four times the boxes; and nothing changes where no such subtree exists.
RC_GTEST_PROP(OccupancyGeometryProperty, FlattenedSubtreesKeepEveryLeafsClass, (std::uint64_t seed)) {
  const int levels = *rc::gen::inRange(2, 6);
  // Mixed trees: inner nodes of any majority under parents of another, so subtrees to flatten occur.
  const double p_split = 0.01 * *rc::gen::inRange(60, 90), p_base = 0.01 * *rc::gen::inRange(20, 60);
  const OccupancyTree t = make_random_occupancy_tree(cube_grid(levels), seed, RandomTreeParams{levels, p_split, p_base});
  const std::size_t budget = *rc::gen::element<std::size_t>(0, 0, 12, 40);
  const OccupancyGeometry g = build_occupancy_geometry(t, budget);
  const OccupancyGeometry f = flatten_sparse_subtrees(t, g);
  RC_ASSERT(f.tree_revision == g.tree_revision && f.depth_limit == g.depth_limit && f.truncated == g.truncated);
  RC_ASSERT(f.node_box.size() == g.node_box.size());
  RC_ASSERT(f.boxes.size() <= 4 * g.boxes.size());
  for (std::size_t i = 1; i < f.boxes.size(); ++i) RC_ASSERT(f.boxes[i].depth >= f.boxes[i - 1].depth);
  // The innermost box on the path from the root to node n, in geometry x.
  const auto innermost = [&](const OccupancyGeometry& x, std::uint32_t n) -> const OccupancyBox* {
    for (std::uint32_t a = n; a != OccupancyTree::kNone; a = t.node(a).parent) {
      if (x.node_box[a] != OccupancyGeometry::kNoBox) return &x.boxes[x.node_box[a]];
    }
    return nullptr;
  };
  std::size_t flattened = 0, leaves = 0;
  for (std::uint32_t n = 0; n < f.node_box.size(); ++n) {
    if (f.node_box[n] == OccupancyGeometry::kNoBox) continue;
    const OccupancyBox& b = f.boxes[f.node_box[n]];
    RC_ASSERT(b.node == n);
    if (g.node_box[n] != OccupancyGeometry::kNoBox &&
        std::memcmp(&b, &g.boxes[g.node_box[n]], sizeof(OccupancyBox)) == 0) {
      continue;
    }
    // A leaf of a flattened subtree: sampled, directly inside EMPTY, under a sampled box of g inside EMPTY.
    ++flattened;
    RC_ASSERT(effective_leaf(t, g, n) && needs_sampling(b.cls) && b.cls == effective_class(t, g, n));
    RC_ASSERT(b.parent_cls == C::Empty && b.depth == t.node(n).depth);
    const Box3 clipped = t.clipped_box(n);
    RC_ASSERT(std::memcmp(&b.box, &clipped, sizeof(Box3)) == 0);
    bool under = false;
    for (std::uint32_t a = t.node(n).parent; a != OccupancyTree::kNone && !under; a = t.node(a).parent) {
      const std::uint32_t i = g.node_box[a];
      under = i != OccupancyGeometry::kNoBox && needs_sampling(g.boxes[i].cls) && g.boxes[i].parent_cls == C::Empty &&
              f.node_box[a] == OccupancyGeometry::kNoBox;
    }
    RC_ASSERT(under);
  }
  for (const OccupancyBox& leaf : leaf_boxes(t, g.depth_limit)) {
    ++leaves;
    const OccupancyBox* bf = innermost(f, leaf.node);
    const OccupancyBox* bg = innermost(g, leaf.node);
    RC_ASSERT(bg != nullptr && bg->cls == leaf.cls);  // Alg. 2's nesting
    RC_ASSERT(bf != nullptr && bf->cls == leaf.cls);
  }
  if (flattened == 0) RC_ASSERT(f.boxes.size() == g.boxes.size());
  RC_TAG(flattened > 0 ? "flattened" : "unchanged");
  RC_ASSERT(leaves > 0u);
}

}  // namespace
}  // namespace sl
