// The occupancy histogram tree (paper §5, Alg. 1; DESIGN.md "Occupancy histogram tree"): an octree over culling
// blocks whose leaves hold an occupancy class and whose inner nodes hold histograms of the classes below them,
// weighted by the number of finest-level blocks, with the class chosen by majority vote.
//
// The tree covers the enclosing power-of-two cube of blocks (2^levels() per axis); blocks outside the
// volume count as EMPTY. Nodes live in one flat array; a node's children are 8 contiguous nodes
// (child i: bit 0 = upper half in x, bit 1 = y, bit 2 = z). Freed child groups are reused, so node
// indices stay stable while the tree grows, collapses and retires nodes (the out-of-core path).
// Not thread-safe: edit it from one thread, then build geometry and orders from it.
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "core/occupancy/block_metadata.h"
#include "core/util/config.h"
#include "core/util/math.h"
#include "core/occupancy/occupancy_class.h"
#include "core/util/ray.h"

namespace sl {

struct OccupancyNode {
  std::uint64_t count[kOccupancyClassCount] = {0, 0, 0};  // weighted histogram, indexed by class
  ivec3 lo{0, 0, 0};                  // first block covered (block coordinates)
  std::uint32_t children = 0xFFFFFFFFu;  // first of 8 contiguous children; kNone for a leaf
  std::uint32_t parent = 0xFFFFFFFFu;    // kNone for the root
  std::uint32_t last_used = 0;        // frame stamp for LRU retirement (paper §8.3)
  std::uint8_t depth = 0;             // 0 = root; levels() = one block
  OccupancyClass cls = OccupancyClass::Unknown;  // leaf: culled class; inner: majority vote
  std::uint8_t pad[2] = {0, 0};
};
static_assert(sizeof(OccupancyNode) == 56, "OccupancyNode layout");

// Majority vote over a histogram; ties go NON_EMPTY > UNKNOWN > EMPTY (the conservative order).
SL_HOST_DEVICE inline OccupancyClass majority_vote(const std::uint64_t count[kOccupancyClassCount]) {
  OccupancyClass best = OccupancyClass::NonEmpty;
  std::uint64_t n = count[int(OccupancyClass::NonEmpty)];
  if (count[int(OccupancyClass::Unknown)] > n) {
    best = OccupancyClass::Unknown;
    n = count[int(OccupancyClass::Unknown)];
  }
  if (count[int(OccupancyClass::Empty)] > n) best = OccupancyClass::Empty;
  return best;
}

// The most conservative class of a region: NON_EMPTY if anything in it is, else UNKNOWN if anything
// is, else EMPTY. Used where a subtree is cut off (geometry box budget).
SL_HOST_DEVICE inline OccupancyClass conservative_class(const std::uint64_t count[kOccupancyClassCount]) {
  if (count[int(OccupancyClass::NonEmpty)] > 0) return OccupancyClass::NonEmpty;
  if (count[int(OccupancyClass::Unknown)] > 0) return OccupancyClass::Unknown;
  return OccupancyClass::Empty;
}

// The class culling gave one region of the tree: the node at `depth` covering level-0 block `block`
// (out of core: a culling block of pyramid level l is the node at depth levels() - l).
struct RegionClass {
  int depth = 0;
  ivec3 block{0, 0, 0};
  OccupancyClass cls = OccupancyClass::Unknown;
};

class OccupancyTree {
 public:
  static constexpr std::uint32_t kNone = 0xFFFFFFFFu;
  static constexpr int kMaxLevels = 20;
  using BlockClassifier = std::function<OccupancyClass(ivec3 block)>;

  OccupancyTree() = default;
  // A single leaf root of class `root` (UNKNOWN: the start of lazy growth, paper Fig. 6).
  explicit OccupancyTree(const BlockGrid& grid, OccupancyClass root = OccupancyClass::Unknown);
  // Full tree from one class per block (block_index order), homogeneous subtrees collapsed.
  static OccupancyTree from_block_classes(const BlockGrid& grid, std::span<const OccupancyClass> classes);

  // TF/label change in core: rebuild from new per-block classes (made from the cached metadata by
  // classify_blocks; no metadata is recomputed here).
  void reclassify(std::span<const OccupancyClass> classes);
  // TF/label change out of core, where classes are known only for the regions rays asked for, each at its level of
  // detail: restart from one UNKNOWN root and set every region with set_region_class in the order given, coarse
  // before fine (a finer region splits the coarser leaf around it; the other new children start UNKNOWN and regrow
  // on demand), marking each used in `frame` (DESIGN.md "Occupancy histogram tree": re-cull from cached metadata,
  // nothing is reloaded). Counts above the regions are not updated: call propagate().
  void recull(std::span<const RegionClass> regions, std::uint32_t frame);
  // Changed by every edit, and unique across all trees of the process, so a cache keyed on it (the
  // frame pipeline's geometry and lists) never mistakes a rebuilt tree for the one it was built from.
  // Geometry built from the tree records it (stale geometry is an error).
  std::uint64_t revision() const { return revision_; }

  const BlockGrid& grid() const { return grid_; }
  int levels() const { return levels_; }  // block level = depth levels()
  std::uint32_t root() const { return 0; }
  const OccupancyNode& node(std::uint32_t i) const { return nodes_[i]; }
  const std::vector<OccupancyNode>& nodes() const { return nodes_; }  // includes free slots
  std::size_t node_count() const { return nodes_.size() - 8 * free_groups_.size(); }  // live nodes
  std::size_t leaf_count() const;
  // Memory held: the node pool (free groups included, reused before it grows) and the free list.
  std::size_t memory_bytes() const {
    return nodes_.capacity() * sizeof(OccupancyNode) + free_groups_.capacity() * sizeof(std::uint32_t);
  }
  bool is_leaf(std::uint32_t i) const { return nodes_[i].children == kNone; }
  std::uint32_t child(std::uint32_t i, int octant) const { return nodes_[i].children + std::uint32_t(octant); }

  int size_blocks(std::uint32_t i) const { return 1 << (levels_ - nodes_[i].depth); }
  std::uint64_t weight(std::uint32_t i) const { return std::uint64_t(1) << (3 * (levels_ - nodes_[i].depth)); }
  std::uint64_t inside_blocks(std::uint32_t i) const;  // blocks of the node inside the volume
  bool outside(std::uint32_t i) const { return inside_blocks(i) == 0; }  // wholly outside the volume
  Box3 node_box(std::uint32_t i) const;     // world box, not clipped (split planes at its centre)
  Box3 clipped_box(std::uint32_t i) const;  // world box clipped to the volume box
  vec3 node_center(std::uint32_t i) const;
  // The one descent of the tree (octant of the block against each node's centre): the node at `depth`
  // covering `block`, or the leaf above it where the tree is coarser.
  std::uint32_t descend(ivec3 block, int depth) const;
  std::uint32_t find_leaf(ivec3 block) const { return descend(block, levels_); }  // leaf covering a block

  // --- editing (lazy growth, tests) ---
  // Splits a leaf into 8 children: UNKNOWN, or EMPTY where wholly outside the volume. Returns the
  // first child. Counts above are not updated: call propagate_up(leaf) or propagate().
  std::uint32_t refine(std::uint32_t leaf);
  void set_leaf_class(std::uint32_t leaf, OccupancyClass c);  // sets its counts, not its ancestors'
  // As descend, but refines leaves on the way, so the node returned is at `depth` (lazy growth, §8.2).
  std::uint32_t descend_refining(ivec3 block, int depth);
  // Culling result for a region (lazy growth, paper §8.2): the node at region.depth covering
  // region.block, reached with descend_refining. A leaf takes the class; where finer nodes exist, only
  // their UNKNOWN leaves inside the volume take it (what is known finer stays). Counts above are not
  // updated. Returns the node.
  std::uint32_t set_region_class(const RegionClass& region);
  void propagate();                                            // Alg. 1 over the whole tree
  void propagate_up(std::uint32_t node);                       // Alg. 1 on the path to the root
  // If the subtree of `node` is homogeneous (all its blocks inside the volume of one class), turns it
  // into one leaf of that class (paper §8.2). Counts must be current. Returns whether it collapsed.
  bool collapse(std::uint32_t node);
  void collapse_homogeneous();  // top-down over the whole tree
  // LRU (paper §8.3): marks a node and its ancestors used in `frame`; retires inner nodes unused for
  // more than max_age frames (a homogeneous subtree keeps its class, a mixed one becomes UNKNOWN).
  void touch(std::uint32_t node, std::uint32_t frame);
  void retire_unused(std::uint32_t frame, std::uint32_t max_age);

 private:
  std::uint32_t alloc_group();
  void free_subtree_children(std::uint32_t node);
  void make_leaf(std::uint32_t node, OccupancyClass c);
  void sum_children(std::uint32_t node);
  bool homogeneous(std::uint32_t node, OccupancyClass& c) const;
  void build(std::uint32_t node, const BlockClassifier& classify);
  void propagate_rec(std::uint32_t node);
  void collapse_rec(std::uint32_t node);
  void retire_rec(std::uint32_t node, std::uint32_t frame, std::uint32_t max_age);
  template <class Fn> void for_each_leaf(std::uint32_t node, Fn&& fn) const;
  void bump_revision();
  template <class Tree> static std::uint32_t descend_impl(Tree& tree, ivec3 block, int depth);

  BlockGrid grid_;
  int levels_ = 0;
  std::vector<OccupancyNode> nodes_;
  std::vector<std::uint32_t> free_groups_;
  std::uint64_t revision_ = 0;
};

// Random subdivision like segment_rules.py's generator (for property tests and benchmarks): split with
// probability p_split while depth < max_depth; a leaf takes `base` with probability p_base, otherwise
// one of EMPTY, EMPTY, EMPTY, NON_EMPTY, UNKNOWN. Classes are propagated, nothing is collapsed.
struct RandomTreeParams {
  int max_depth = 4;
  double p_split = 0.7;
  double p_base = 0.6;
};
OccupancyTree make_random_occupancy_tree(const BlockGrid& grid, std::uint64_t seed, const RandomTreeParams& p);

}  // namespace sl
