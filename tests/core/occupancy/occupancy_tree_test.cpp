// Occupancy histogram tree (paper §5, Alg. 1): weighted histograms, majority vote and its tie order,
// collapse, non-power-of-two volumes, re-culling from cached metadata (in core from block classes, out
// of core from culled regions), the one descent, lazy growth and LRU retirement.
#include "core/occupancy/occupancy_tree.h"

#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include <vector>

#include "core/occupancy/block_metadata.h"
#include "core/occupancy/culling.h"
#include "core/scene/transfer_function.h"
#include "core/scene/volume.h"

namespace sl {
namespace {

using C = OccupancyClass;

TEST(OccupancyTree, MajorityVoteTiesGoNonEmptyThenUnknownThenEmpty) {
  auto vote = [](std::uint64_t e, std::uint64_t ne, std::uint64_t u) {
    const std::uint64_t c[3] = {e, ne, u};
    return majority_vote(c);
  };
  EXPECT_EQ(vote(3, 1, 2), C::Empty);
  EXPECT_EQ(vote(1, 3, 2), C::NonEmpty);
  EXPECT_EQ(vote(1, 2, 3), C::Unknown);
  EXPECT_EQ(vote(2, 2, 2), C::NonEmpty);  // three-way tie
  EXPECT_EQ(vote(2, 2, 0), C::NonEmpty);
  EXPECT_EQ(vote(2, 0, 2), C::Unknown);
  EXPECT_EQ(vote(0, 2, 2), C::NonEmpty);
  const std::uint64_t c[3] = {5, 0, 1};
  EXPECT_EQ(conservative_class(c), C::Unknown);
  const std::uint64_t d[3] = {5, 1, 1};
  EXPECT_EQ(conservative_class(d), C::NonEmpty);
  const std::uint64_t e[3] = {5, 0, 0};
  EXPECT_EQ(conservative_class(e), C::Empty);
}

BlockGrid cube_grid(int levels, int block = 4) {
  return make_block_grid(ivec3(block << levels), vec3(1.0f), block);
}

TEST(OccupancyTree, HistogramsAreWeightedByFinestBlocks) {
  OccupancyTree t(cube_grid(2), C::Empty);  // 4x4x4 blocks
  const std::uint32_t c = t.refine(t.root());
  // Child 0 splits into 7 NON_EMPTY blocks and 1 EMPTY; the other 7 children stay coarse EMPTY leaves.
  const std::uint32_t g = t.refine(c + 0);
  for (int k = 0; k < 8; ++k) t.set_leaf_class(g + k, k == 3 ? C::Empty : C::NonEmpty);
  for (int k = 1; k < 8; ++k) t.set_leaf_class(c + k, C::Empty);
  t.propagate();
  EXPECT_EQ(t.node(c).cls, C::NonEmpty);
  EXPECT_EQ(t.node(c).count[int(C::NonEmpty)], 7u);
  // A coarse leaf counts for all 8 blocks it covers: the root is 57 EMPTY vs 7 NON_EMPTY.
  EXPECT_EQ(t.node(t.root()).count[int(C::Empty)], 57u);
  EXPECT_EQ(t.node(t.root()).count[int(C::NonEmpty)], 7u);
  EXPECT_EQ(t.node(t.root()).cls, C::Empty);
  EXPECT_EQ(t.weight(t.root()), 64u);
}

TEST(OccupancyTree, TieInAnInnerNodeIsConservative) {
  OccupancyTree t(cube_grid(1), C::Empty);
  const std::uint32_t c = t.refine(t.root());
  for (int k = 0; k < 8; ++k) t.set_leaf_class(c + k, k < 4 ? C::Empty : C::Unknown);
  t.propagate();
  EXPECT_EQ(t.node(t.root()).cls, C::Unknown);
  t.set_leaf_class(c + 7, C::NonEmpty);  // 4 E, 3 U, 1 NE: EMPTY wins outright
  t.propagate_up(c + 7);
  EXPECT_EQ(t.node(t.root()).cls, C::Empty);
}

TEST(OccupancyTree, FromBlockClassesReproducesEveryBlockAndCollapses) {
  const BlockGrid g = cube_grid(3);  // 8^3 blocks
  std::vector<C> classes(g.block_count(), C::Empty);
  // One NON_EMPTY block and a homogeneous UNKNOWN octant.
  classes[g.block_index(ivec3(1, 2, 3))] = C::NonEmpty;
  for (int z = 4; z < 8; ++z)
    for (int y = 4; y < 8; ++y)
      for (int x = 4; x < 8; ++x) classes[g.block_index(ivec3(x, y, z))] = C::Unknown;
  const OccupancyTree t = OccupancyTree::from_block_classes(g, classes);
  for (std::size_t i = 0; i < g.block_count(); ++i) {
    const ivec3 b = g.block_coord(i);
    EXPECT_EQ(t.node(t.find_leaf(b)).cls, classes[i]) << b.x << "," << b.y << "," << b.z;
  }
  // The UNKNOWN octant is one leaf at depth 1; only the path to the NON_EMPTY block is refined.
  EXPECT_EQ(t.node(t.find_leaf(ivec3(5, 5, 5))).depth, 1);
  EXPECT_EQ(t.leaf_count(), 8u + 7u + 7u);
  EXPECT_EQ(t.node_count(), 1u + 8u + 8u + 8u);
  EXPECT_EQ(t.node(t.root()).count[int(C::Unknown)], 64u);
  EXPECT_EQ(t.node(t.root()).count[int(C::NonEmpty)], 1u);
}

TEST(OccupancyTree, HomogeneousVolumeIsOneLeaf) {
  const BlockGrid g = cube_grid(3);
  const OccupancyTree t = OccupancyTree::from_block_classes(g, std::vector<C>(g.block_count(), C::Empty));
  EXPECT_EQ(t.node_count(), 1u);
  EXPECT_TRUE(t.is_leaf(t.root()));
  EXPECT_EQ(t.node(t.root()).cls, C::Empty);
}

TEST(OccupancyTree, NonPowerOfTwoVolumeCountsOutsideAsEmpty) {
  const BlockGrid g = make_block_grid(ivec3(97, 131, 73), vec3(1.0f), 16);
  EXPECT_EQ(g.blocks, ivec3(7, 9, 5));
  std::vector<C> classes(g.block_count(), C::NonEmpty);
  classes[0] = C::Empty;
  const OccupancyTree t = OccupancyTree::from_block_classes(g, classes);
  EXPECT_EQ(t.levels(), 4);  // 16^3 cube of blocks
  const OccupancyNode& root = t.node(t.root());
  EXPECT_EQ(root.count[int(C::NonEmpty)], 7u * 9u * 5u - 1u);
  EXPECT_EQ(root.count[int(C::Empty)], 4096u - 7u * 9u * 5u + 1u);
  EXPECT_EQ(root.cls, C::Empty);  // outside the volume outvotes it
  EXPECT_EQ(t.inside_blocks(t.root()), 315u);
  // Clipped boxes: the root box clipped is the volume box.
  EXPECT_EQ(t.clipped_box(t.root()).hi, vec3(97.0f, 131.0f, 73.0f));
  EXPECT_EQ(t.node_box(t.root()).hi, vec3(256.0f));
  // A region inside and all NON_EMPTY that straddles the volume face collapses to one leaf.
  std::vector<C> all(g.block_count(), C::NonEmpty);
  const OccupancyTree u = OccupancyTree::from_block_classes(g, all);
  EXPECT_EQ(u.node_count(), 1u);
  EXPECT_EQ(u.node(u.root()).cls, C::NonEmpty);
  EXPECT_EQ(u.node(u.root()).count[int(C::Empty)], 4096u - 315u);
}

TEST(OccupancyTree, ReclassifyReusesMetadata) {
  VolumeDesc d;
  d.dims = ivec3(40, 24, 20);
  Volume v(d);
  for (int z = 0; z < 20; ++z)
    for (int y = 0; y < 24; ++y)
      for (int x = 0; x < 40; ++x) v.set(x, y, z, float((x * 7 + y * 3 + z) % 50 + (x >= 31 ? 150 : 0)));
  const BlockGrid g = make_block_grid(d.dims, d.spacing, 8);
  const std::uint64_t before = block_metadata_computations();
  const BlockMetadataTable table = compute_all_block_metadata(g, v.view(), nullptr);
  EXPECT_EQ(block_metadata_computations() - before, g.block_count());

  const TransferFunction opaque_high({{0.0f, vec4(0.0f)}, {140.0f, vec4(0.0f)}, {200.0f, vec4(1.0f)}});
  const TransferFunction opaque_low({{0.0f, vec4(1.0f)}, {20.0f, vec4(1.0f)}, {30.0f, vec4(0.0f)}});
  CullParams p;
  p.tf = &opaque_high;
  OccupancyTree t = OccupancyTree::from_block_classes(g, classify_blocks(table, p));
  EXPECT_EQ(t.node(t.find_leaf(ivec3(4, 0, 0))).cls, C::NonEmpty);  // x >= 31
  EXPECT_EQ(t.node(t.find_leaf(ivec3(0, 0, 0))).cls, C::Empty);

  const std::uint64_t computed = block_metadata_computations();
  p.tf = &opaque_low;  // a TF change: re-cull from the cached metadata
  const std::vector<C> classes = classify_blocks(table, p);
  const std::uint64_t revision = t.revision();
  t.reclassify(classes);
  EXPECT_EQ(block_metadata_computations(), computed);  // nothing recomputed
  EXPECT_NE(t.revision(), revision);                   // geometry and lists built before are stale
  for (std::size_t i = 0; i < g.block_count(); ++i) EXPECT_EQ(t.node(t.find_leaf(g.block_coord(i))).cls, classes[i]);
  EXPECT_EQ(t.node(t.find_leaf(ivec3(4, 0, 0))).cls, C::Empty);
  EXPECT_EQ(t.node(t.find_leaf(ivec3(0, 0, 0))).cls, C::NonEmpty);
}

TEST(OccupancyTree, LazyGrowthRefinesClassifiesAndCollapses) {
  const BlockGrid g = make_block_grid(ivec3(40, 32, 32), vec3(1.0f), 8);  // 5x4x4 blocks, 8^3 cube
  OccupancyTree t(g);
  EXPECT_EQ(t.node_count(), 1u);
  EXPECT_EQ(t.node(t.root()).cls, C::Unknown);  // Fig. 6, left
  const std::uint32_t c = t.refine(t.root());
  EXPECT_EQ(t.node(c + 1).cls, C::Unknown);  // x-upper half [4, 8) blocks: partly inside
  const std::uint32_t c1 = t.refine(c + 1);
  EXPECT_EQ(t.node(c1 + 1).cls, C::Empty);    // blocks [6, 8) in x: wholly outside
  EXPECT_EQ(t.node(c1 + 0).cls, C::Unknown);  // blocks [4, 6): partly inside
  // Culling resolves the lower octants to EMPTY: homogeneous subtrees collapse (Fig. 6, right).
  for (int k = 0; k < 8; ++k) {
    if (k != 1) t.set_leaf_class(c + k, C::Empty);
  }
  for (int k = 0; k < 8; ++k) {
    if (t.node(c1 + k).cls == C::Unknown) t.set_leaf_class(c1 + k, C::Empty);
  }
  t.propagate_up(c1);
  EXPECT_EQ(t.node(t.root()).count[int(C::Empty)], 512u);
  t.collapse_homogeneous();
  EXPECT_EQ(t.node_count(), 1u);
  EXPECT_EQ(t.node(t.root()).cls, C::Empty);
  // Freed groups are reused: growing again does not enlarge the array.
  const std::size_t slots = t.nodes().size();
  t.set_leaf_class(t.root(), C::Unknown);
  t.refine(t.root());
  EXPECT_EQ(t.nodes().size(), slots);
}

TEST(OccupancyTree, LeastRecentlyUsedSubtreesRetire) {
  const BlockGrid g = cube_grid(2);
  std::vector<C> classes(g.block_count(), C::Empty);
  classes[g.block_index(ivec3(0, 0, 0))] = C::NonEmpty;
  classes[g.block_index(ivec3(3, 3, 3))] = C::NonEmpty;
  OccupancyTree t = OccupancyTree::from_block_classes(g, classes);
  const std::uint32_t a = t.find_leaf(ivec3(0, 0, 0));
  const std::uint32_t b = t.find_leaf(ivec3(3, 3, 3));
  ASSERT_EQ(t.node(a).depth, 2);
  t.touch(a, 10);
  t.touch(b, 3);
  t.retire_unused(12, 4);  // b's subtree last used at 3: retired; a's at 10: kept
  EXPECT_EQ(t.node(t.find_leaf(ivec3(0, 0, 0))).cls, C::NonEmpty);
  const std::uint32_t r = t.find_leaf(ivec3(3, 3, 3));
  EXPECT_EQ(t.node(r).depth, 1);
  EXPECT_EQ(t.node(r).cls, C::Unknown);  // heterogeneous: unknown again, regrows on demand
  EXPECT_EQ(t.node(t.root()).count[int(C::Unknown)], 8u);
}

TEST(OccupancyTree, DescendStopsAtDepthOrAtTheLeafAboveAndRefiningReachesTheDepth) {
  const BlockGrid g = cube_grid(3);  // 8^3 blocks
  OccupancyTree t(g);
  EXPECT_EQ(t.descend(ivec3(5, 2, 7), 2), t.root());  // only a root: the leaf above depth 2
  const std::uint32_t n = t.descend_refining(ivec3(5, 2, 7), 2);
  EXPECT_EQ(t.node(n).depth, 2);
  EXPECT_EQ(t.node(n).lo, ivec3(4, 2, 6));  // the depth-2 node (2 blocks wide) holding it
  EXPECT_EQ(t.size_blocks(n), 2);
  EXPECT_EQ(t.descend(ivec3(5, 2, 7), 2), n);
  EXPECT_EQ(t.descend(ivec3(5, 2, 7), 3), n);  // no finer node yet
  EXPECT_EQ(t.find_leaf(ivec3(5, 2, 7)), n);
  EXPECT_EQ(t.node(t.descend(ivec3(5, 2, 7), 1)).depth, 1);
  EXPECT_EQ(t.node_count(), 1u + 8u + 8u);  // refined the root and one child on the way
  EXPECT_EQ(t.node(t.find_leaf(ivec3(0, 0, 0))).depth, 1);
}

TEST(OccupancyTree, RegionClassFillsOnlyUnknownLeavesBelowKnownFinerOnes) {
  const BlockGrid g = cube_grid(2);  // 4^3 blocks
  OccupancyTree t(g);
  // A fine region first, then the coarse region around it: the fine class stays.
  t.set_region_class(RegionClass{2, ivec3(1, 1, 1), C::NonEmpty});
  const std::uint32_t coarse = t.set_region_class(RegionClass{1, ivec3(0, 0, 0), C::Empty});
  EXPECT_EQ(t.node(coarse).depth, 1);
  EXPECT_FALSE(t.is_leaf(coarse));
  EXPECT_EQ(t.node(t.find_leaf(ivec3(1, 1, 1))).cls, C::NonEmpty);
  EXPECT_EQ(t.node(t.find_leaf(ivec3(0, 0, 0))).cls, C::Empty);
  EXPECT_EQ(t.node(t.find_leaf(ivec3(2, 0, 0))).cls, C::Unknown);  // another depth-1 region: untouched
  // A region that is a leaf takes the class outright.
  t.set_region_class(RegionClass{1, ivec3(2, 0, 0), C::NonEmpty});
  EXPECT_EQ(t.node(t.find_leaf(ivec3(3, 1, 1))).cls, C::NonEmpty);
  t.propagate();
  EXPECT_EQ(t.node(t.root()).count[int(C::NonEmpty)], 1u + 8u);
}

TEST(OccupancyTree, RecullRebuildsFromRegionsCoarseBeforeFineAndMarksThemUsed) {
  const BlockGrid g = make_block_grid(ivec3(40, 32, 32), vec3(1.0f), 8);  // 5x4x4 blocks, 8^3 cube
  OccupancyTree t(g);
  t.set_region_class(RegionClass{3, ivec3(4, 3, 3), C::NonEmpty});  // knowledge the re-cull replaces
  const std::uint64_t revision = t.revision();
  // As out of core: culling blocks of pyramid levels 2, 1 and 0, coarse before fine.
  const std::vector<RegionClass> regions = {
      {1, ivec3(0, 0, 0), C::Empty},
      {2, ivec3(4, 0, 0), C::NonEmpty},  // refines the depth-1 leaf around it
      {3, ivec3(4, 2, 0), C::Empty},     // refines a depth-2 leaf of that one
  };
  t.recull(regions, 7);
  EXPECT_NE(t.revision(), revision);
  EXPECT_EQ(t.node(t.find_leaf(ivec3(0, 0, 0))).cls, C::Empty);
  EXPECT_EQ(t.node(t.find_leaf(ivec3(3, 3, 3))).cls, C::Empty);
  EXPECT_EQ(t.node(t.find_leaf(ivec3(4, 1, 1))).cls, C::NonEmpty);
  EXPECT_EQ(t.node(t.find_leaf(ivec3(4, 2, 0))).cls, C::Empty);
  EXPECT_EQ(t.node(t.find_leaf(ivec3(4, 2, 0))).depth, 3);
  // Not covered by a region: UNKNOWN, to regrow on demand (the old NON_EMPTY block among them).
  EXPECT_EQ(t.node(t.find_leaf(ivec3(4, 3, 0))).cls, C::Unknown);
  EXPECT_EQ(t.node(t.find_leaf(ivec3(4, 3, 3))).cls, C::Unknown);
  // The regions' nodes and their ancestors are used in frame 7; nodes only split on the way are not.
  EXPECT_EQ(t.node(t.root()).last_used, 7u);
  EXPECT_EQ(t.node(t.find_leaf(ivec3(0, 0, 0))).last_used, 7u);
  EXPECT_EQ(t.node(t.find_leaf(ivec3(4, 2, 0))).last_used, 7u);
  EXPECT_EQ(t.node(t.find_leaf(ivec3(4, 0, 2))).last_used, 0u);
}

TEST(OccupancyTree, RevisionsDifferAcrossTreesAndEdits) {
  const BlockGrid g = cube_grid(2);
  OccupancyTree a(g), b(g);
  EXPECT_NE(a.revision(), b.revision());  // two fresh trees: a cache keyed on one never takes the other
  const std::uint64_t ra = a.revision();
  a.refine(a.root());
  EXPECT_NE(a.revision(), ra);
  OccupancyTree c = a;  // a copy is the same tree until either changes
  EXPECT_EQ(c.revision(), a.revision());
  c.propagate();
  EXPECT_NE(c.revision(), a.revision());
}

RC_GTEST_PROP(OccupancyTreeProperty, HistogramsMatchTheLeavesBelow, (std::uint64_t seed)) {
  const int levels = *rc::gen::inRange(1, 5);
  const OccupancyTree t = make_random_occupancy_tree(cube_grid(levels), seed, RandomTreeParams{levels, 0.7, 0.6});
  // Brute force over blocks: each node's histogram counts the classes of the leaves covering its blocks.
  const BlockGrid& g = t.grid();
  for (std::uint32_t n = 0; n < t.nodes().size(); ++n) {
    if (t.node(n).cls == C::Invalid) continue;
    std::uint64_t want[3] = {0, 0, 0};
    const int s = t.size_blocks(n);
    for (int z = 0; z < s; ++z)
      for (int y = 0; y < s; ++y)
        for (int x = 0; x < s; ++x) {
          const ivec3 b = t.node(n).lo + ivec3(x, y, z);
          ++want[int(g.inside(b) ? t.node(t.find_leaf(b)).cls : C::Empty)];
        }
    for (int c = 0; c < 3; ++c) RC_ASSERT(t.node(n).count[c] == want[c]);
    if (!t.is_leaf(n)) RC_ASSERT(t.node(n).cls == majority_vote(want));
  }
}

}  // namespace
}  // namespace sl
