#include "core/occupancy/occupancy_tree.h"

#include "core/util/rng.h"

#include <algorithm>
#include <atomic>
#include <type_traits>

namespace sl {

namespace {

// Revisions come from one counter for all trees (see revision()).
std::atomic<std::uint64_t> g_revision{0};

int levels_for(const BlockGrid& g) {
  const int m = std::max(g.blocks.x, std::max(g.blocks.y, g.blocks.z));
  int l = 0;
  while ((1 << l) < m) ++l;
  return l;
}

}  // namespace

OccupancyTree::OccupancyTree(const BlockGrid& grid, OccupancyClass root) : grid_(grid) {
  SL_CHECK(grid.blocks.x > 0 && grid.blocks.y > 0 && grid.blocks.z > 0);
  levels_ = levels_for(grid);
  SL_CHECK(levels_ <= kMaxLevels);
  nodes_.push_back(OccupancyNode{});
  set_leaf_class(0, root);
}

OccupancyTree OccupancyTree::from_block_classes(const BlockGrid& grid, std::span<const OccupancyClass> classes) {
  SL_CHECK(classes.size() == grid.block_count());
  OccupancyTree t(grid, OccupancyClass::Unknown);
  t.build(0, [&](ivec3 b) { return classes[grid.block_index(b)]; });
  return t;
}

void OccupancyTree::reclassify(std::span<const OccupancyClass> classes) {
  *this = from_block_classes(grid_, classes);
}

void OccupancyTree::recull(std::span<const RegionClass> regions, std::uint32_t frame) {
  *this = OccupancyTree(grid_, OccupancyClass::Unknown);
  for (const RegionClass& r : regions) touch(set_region_class(r), frame);
}

std::size_t OccupancyTree::leaf_count() const {
  std::size_t n = 0;
  for_each_leaf(0, [&](std::uint32_t) { ++n; });
  return n;
}

std::uint64_t OccupancyTree::inside_blocks(std::uint32_t i) const {
  const OccupancyNode& n = nodes_[i];
  const int s = size_blocks(i);
  std::uint64_t r = 1;
  for (int a = 0; a < 3; ++a) r *= std::uint64_t(std::clamp(grid_.blocks[a] - n.lo[a], 0, s));
  return r;
}

Box3 OccupancyTree::node_box(std::uint32_t i) const {
  const ivec3 lo = nodes_[i].lo * grid_.block;
  const ivec3 hi = (nodes_[i].lo + size_blocks(i)) * grid_.block;
  Box3 b;
  for (int a = 0; a < 3; ++a) {
    b.lo[a] = grid_.plane(a, lo[a]);
    b.hi[a] = grid_.plane(a, hi[a]);
  }
  return b;
}

Box3 OccupancyTree::clipped_box(std::uint32_t i) const {
  return grid_.voxel_box(nodes_[i].lo * grid_.block, (nodes_[i].lo + size_blocks(i)) * grid_.block);
}

vec3 OccupancyTree::node_center(std::uint32_t i) const {
  const ivec3 c = (nodes_[i].lo * 2 + size_blocks(i)) * grid_.block;  // twice the centre, in voxels
  return vec3(0.5f * float(c.x) * grid_.spacing.x, 0.5f * float(c.y) * grid_.spacing.y,
              0.5f * float(c.z) * grid_.spacing.z);
}

template <class Tree>
std::uint32_t OccupancyTree::descend_impl(Tree& t, ivec3 block, int depth) {
  std::uint32_t i = t.root();
  while (t.nodes_[i].depth < depth) {
    if (t.is_leaf(i)) {
      if constexpr (std::is_const_v<Tree>) {
        break;
      } else {
        t.refine(i);
      }
    }
    const ivec3 c = t.nodes_[i].lo + t.size_blocks(i) / 2;
    i = t.child(i, (block.x >= c.x ? 1 : 0) | (block.y >= c.y ? 2 : 0) | (block.z >= c.z ? 4 : 0));
  }
  return i;
}

std::uint32_t OccupancyTree::descend(ivec3 block, int depth) const { return descend_impl(*this, block, depth); }

std::uint32_t OccupancyTree::descend_refining(ivec3 block, int depth) { return descend_impl(*this, block, depth); }

std::uint32_t OccupancyTree::set_region_class(const RegionClass& r) {
  const std::uint32_t n = descend_refining(r.block, r.depth);
  if (is_leaf(n)) {
    set_leaf_class(n, r.cls);
    return n;
  }
  std::vector<std::uint32_t> stack{n};
  while (!stack.empty()) {
    const std::uint32_t m = stack.back();
    stack.pop_back();
    if (is_leaf(m)) {
      if (nodes_[m].cls == OccupancyClass::Unknown && !outside(m)) set_leaf_class(m, r.cls);
    } else {
      for (int o = 0; o < 8; ++o) stack.push_back(child(m, o));
    }
  }
  return n;
}

void OccupancyTree::bump_revision() { revision_ = g_revision.fetch_add(1, std::memory_order_relaxed) + 1; }

std::uint32_t OccupancyTree::alloc_group() {
  if (!free_groups_.empty()) {
    const std::uint32_t g = free_groups_.back();
    free_groups_.pop_back();
    return g;
  }
  SL_CHECK(nodes_.size() + 8 < std::size_t(kNone));
  const std::uint32_t g = std::uint32_t(nodes_.size());
  nodes_.resize(nodes_.size() + 8);
  return g;
}

void OccupancyTree::free_subtree_children(std::uint32_t node) {
  const std::uint32_t c = nodes_[node].children;
  if (c == kNone) return;
  for (int k = 0; k < 8; ++k) free_subtree_children(c + k);
  for (int k = 0; k < 8; ++k) nodes_[c + k].cls = OccupancyClass::Invalid;  // marks a free slot
  free_groups_.push_back(c);
  nodes_[node].children = kNone;
}

std::uint32_t OccupancyTree::refine(std::uint32_t leaf) {
  SL_CHECK(is_leaf(leaf) && nodes_[leaf].depth < levels_);
  bump_revision();
  const std::uint32_t c = alloc_group();  // may reallocate nodes_: index, do not hold references
  const int h = size_blocks(leaf) / 2;
  for (int k = 0; k < 8; ++k) {
    OccupancyNode n;
    n.lo = nodes_[leaf].lo + ivec3(k & 1, (k >> 1) & 1, (k >> 2) & 1) * h;
    n.parent = leaf;
    n.depth = std::uint8_t(nodes_[leaf].depth + 1);
    n.last_used = nodes_[leaf].last_used;
    nodes_[c + k] = n;
    set_leaf_class(c + k, outside(c + k) ? OccupancyClass::Empty : OccupancyClass::Unknown);
  }
  nodes_[leaf].children = c;
  return c;
}

void OccupancyTree::set_leaf_class(std::uint32_t leaf, OccupancyClass c) {
  SL_CHECK(is_leaf(leaf) && c != OccupancyClass::Invalid);
  bump_revision();
  OccupancyNode& n = nodes_[leaf];
  n.cls = c;
  // A leaf counts for all the blocks it covers; the part outside the volume counts EMPTY (DESIGN.md "Occupancy
  // histogram tree").
  const std::uint64_t inside = inside_blocks(leaf);
  n.count[0] = n.count[1] = n.count[2] = 0;
  n.count[int(c)] += inside;
  n.count[int(OccupancyClass::Empty)] += weight(leaf) - inside;
}

void OccupancyTree::sum_children(std::uint32_t node) {
  OccupancyNode& n = nodes_[node];
  n.count[0] = n.count[1] = n.count[2] = 0;
  for (int k = 0; k < 8; ++k) {
    for (int c = 0; c < kOccupancyClassCount; ++c) n.count[c] += nodes_[n.children + k].count[c];
  }
  n.cls = majority_vote(n.count);  // Alg. 1, line 9
}

// Alg. 1: depth first, post-order: children's histograms first, then the sum and the vote.
void OccupancyTree::propagate_rec(std::uint32_t node) {
  if (is_leaf(node)) return;
  for (int k = 0; k < 8; ++k) propagate_rec(nodes_[node].children + k);
  sum_children(node);
}

void OccupancyTree::propagate() {
  bump_revision();
  propagate_rec(0);
}

void OccupancyTree::propagate_up(std::uint32_t node) {
  bump_revision();
  for (std::uint32_t i = node; i != kNone; i = nodes_[i].parent) {
    if (!is_leaf(i)) sum_children(i);
  }
}

bool OccupancyTree::homogeneous(std::uint32_t node, OccupancyClass& c) const {
  const OccupancyNode& n = nodes_[node];
  const std::uint64_t inside = inside_blocks(node);
  if (n.count[int(OccupancyClass::Empty)] == weight(node)) {
    c = OccupancyClass::Empty;
    return true;
  }
  for (OccupancyClass k : {OccupancyClass::NonEmpty, OccupancyClass::Unknown}) {
    if (n.count[int(k)] == inside) {
      c = k;
      return true;
    }
  }
  return false;
}

void OccupancyTree::make_leaf(std::uint32_t node, OccupancyClass c) {
  bump_revision();
  free_subtree_children(node);
  set_leaf_class(node, c);
}

bool OccupancyTree::collapse(std::uint32_t node) {
  OccupancyClass c;
  if (is_leaf(node) || !homogeneous(node, c)) return false;
  make_leaf(node, c);  // same counts: the ancestors stay valid
  return true;
}

void OccupancyTree::collapse_rec(std::uint32_t node) {
  if (is_leaf(node) || collapse(node)) return;
  for (int k = 0; k < 8; ++k) collapse_rec(nodes_[node].children + k);
}

void OccupancyTree::collapse_homogeneous() { collapse_rec(0); }

// Builds the subtree of a leaf-to-be from per-block classes, collapsing homogeneous children as soon
// as they are complete, so peak memory stays close to the final tree size.
void OccupancyTree::build(std::uint32_t node, const BlockClassifier& classify) {
  free_subtree_children(node);
  if (outside(node)) return set_leaf_class(node, OccupancyClass::Empty);
  if (nodes_[node].depth == levels_) return set_leaf_class(node, classify(nodes_[node].lo));
  const std::uint32_t c = refine(node);
  for (int k = 0; k < 8; ++k) build(c + k, classify);
  sum_children(node);
  collapse(node);
}

void OccupancyTree::touch(std::uint32_t node, std::uint32_t frame) {
  for (std::uint32_t i = node; i != kNone; i = nodes_[i].parent) {
    nodes_[i].last_used = std::max(nodes_[i].last_used, frame);
  }
}

void OccupancyTree::retire_rec(std::uint32_t node, std::uint32_t frame, std::uint32_t max_age) {
  if (is_leaf(node)) return;
  if (frame > nodes_[node].last_used && frame - nodes_[node].last_used > max_age) {
    OccupancyClass c;
    make_leaf(node, homogeneous(node, c) ? c : OccupancyClass::Unknown);
    return;
  }
  for (int k = 0; k < 8; ++k) retire_rec(nodes_[node].children + k, frame, max_age);
}

void OccupancyTree::retire_unused(std::uint32_t frame, std::uint32_t max_age) {
  retire_rec(0, frame, max_age);
  propagate();
}

template <class Fn>
void OccupancyTree::for_each_leaf(std::uint32_t node, Fn&& fn) const {
  if (is_leaf(node)) return fn(node);
  for (int k = 0; k < 8; ++k) for_each_leaf(nodes_[node].children + k, fn);
}

namespace {

void random_subdivide(OccupancyTree& t, std::uint32_t node, const RandomTreeParams& p, OccupancyClass base,
                      SplitMix64& rng) {
  static constexpr OccupancyClass kPick[5] = {OccupancyClass::Empty, OccupancyClass::Empty, OccupancyClass::Empty,
                                              OccupancyClass::NonEmpty, OccupancyClass::Unknown};
  const int depth = t.node(node).depth;
  if (depth < p.max_depth && depth < t.levels() && rng.uniform_double() < p.p_split) {
    const std::uint32_t c = t.refine(node);
    for (int k = 0; k < 8; ++k) random_subdivide(t, c + k, p, base, rng);
  } else {
    t.set_leaf_class(node, rng.uniform_double() < p.p_base ? base : kPick[rng.next() % 5]);
  }
}

}  // namespace

OccupancyTree make_random_occupancy_tree(const BlockGrid& grid, std::uint64_t seed, const RandomTreeParams& p) {
  SplitMix64 rng{seed};
  static constexpr OccupancyClass kBase[3] = {OccupancyClass::Empty, OccupancyClass::NonEmpty,
                                              OccupancyClass::Unknown};
  const OccupancyClass base = kBase[rng.next() % 3];
  OccupancyTree t(grid, base);
  random_subdivide(t, t.root(), p, base, rng);
  t.propagate();
  return t;
}

}  // namespace sl
