#include "core/occupancy/octree_skip.h"

#include <algorithm>

namespace sl {

SkipOctree::SkipOctree(const BlockGrid& grid, std::span<const OccupancyClass> block_classes) : grid_(grid) {
  SL_CHECK(block_classes.size() == grid.block_count());
  const int m = std::max(grid.blocks.x, std::max(grid.blocks.y, grid.blocks.z));
  while ((1 << levels_) < m) ++levels_;
  nodes_.push_back(SkipOctreeNode{});
  build(0, ivec3(0), 1 << levels_, block_classes);
}

// Bottom-up min/max rule: a leaf is its block's class (UNKNOWN -> NON_EMPTY, outside -> EMPTY); an
// inner node is NON_EMPTY if any child is; a subtree that is all EMPTY becomes one EMPTY leaf.
std::uint8_t SkipOctree::build(std::uint32_t node, ivec3 lo, int size, std::span<const OccupancyClass> classes) {
  constexpr std::uint8_t kEmpty = std::uint8_t(OccupancyClass::Empty);
  constexpr std::uint8_t kNonEmpty = std::uint8_t(OccupancyClass::NonEmpty);
  if (lo.x >= grid_.blocks.x || lo.y >= grid_.blocks.y || lo.z >= grid_.blocks.z) {
    nodes_[node].cls = kEmpty;
    return kEmpty;
  }
  if (size == 1) {
    const OccupancyClass c = classes[grid_.block_index(lo)];
    nodes_[node].cls = c == OccupancyClass::Empty ? kEmpty : kNonEmpty;
    return nodes_[node].cls;
  }
  const std::uint32_t first = std::uint32_t(nodes_.size());
  nodes_.resize(nodes_.size() + 8);
  nodes_[node].children = first;
  const int h = size / 2;
  bool any = false;
  for (int k = 0; k < 8; ++k) {
    const ivec3 clo = lo + ivec3(k & 1, (k >> 1) & 1, (k >> 2) & 1) * h;
    any = build(first + std::uint32_t(k), clo, h, classes) != kEmpty || any;
  }
  if (!any) {
    // All children are empty leaves (their own subtrees already collapsed), so they are the last 8.
    SL_CHECK(nodes_.size() == std::size_t(first) + 8);
    nodes_.resize(first);
    nodes_[node].children = kNone;
  }
  nodes_[node].cls = any ? kNonEmpty : kEmpty;
  return nodes_[node].cls;
}

std::vector<SkipOctree::Leaf> SkipOctree::leaves() const {
  std::vector<Leaf> out;
  struct Item {
    std::uint32_t node;
    ivec3 lo;
    int size;
  };
  std::vector<Item> stack{{0, ivec3(0), 1 << levels_}};
  while (!stack.empty()) {
    const Item it = stack.back();
    stack.pop_back();
    if (it.lo.x >= grid_.blocks.x || it.lo.y >= grid_.blocks.y || it.lo.z >= grid_.blocks.z) continue;
    const SkipOctreeNode& n = nodes_[it.node];
    if (n.children == kNone) {
      out.push_back(Leaf{grid_.voxel_box(it.lo * grid_.block, (it.lo + it.size) * grid_.block),
                         OccupancyClass(n.cls)});
      continue;
    }
    const int h = it.size / 2;
    for (int k = 0; k < 8; ++k) {
      stack.push_back({n.children + std::uint32_t(k), it.lo + ivec3(k & 1, (k >> 1) & 1, (k >> 2) & 1) * h, h});
    }
  }
  return out;
}

}  // namespace sl
