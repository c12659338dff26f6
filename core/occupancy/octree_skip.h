// The octree baseline (DESIGN.md "Ray casting"): a standard min/max octree over the culling blocks, traversed
// with kd-restart (Foley & Sugerman 2005): from the current t, descend from the root to the leaf that
// holds the ray there, sample or skip that leaf, advance t to its exit, restart.
//
// Unlike the occupancy histogram tree, an inner node is NON_EMPTY if any child is (UNKNOWN counts as
// NON_EMPTY); only all-empty subtrees become (empty) leaves. Regions outside the volume are EMPTY.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "core/occupancy/block_metadata.h"
#include "core/util/config.h"
#include "core/occupancy/occupancy_class.h"
#include "core/util/ray.h"

namespace sl {

struct SkipOctreeNode {
  std::uint32_t children = 0xFFFFFFFFu;  // first of 8 contiguous children (bit 0 = x); kNone = leaf
  std::uint8_t cls = 0;                  // OccupancyClass: Empty or NonEmpty
  std::uint8_t pad[3] = {0, 0, 0};
};
static_assert(sizeof(SkipOctreeNode) == 8, "SkipOctreeNode layout");

// One kd-restart step: the leaf holding the ray at t0, its span [t0, t1) and class, and the number of
// nodes visited on the way down (depth complexity, paper Fig. 7 right).
struct KdRestartStep {
  float t0 = 0.0f;
  float t1 = 0.0f;
  OccupancyClass cls = OccupancyClass::Empty;
  std::uint32_t nodes_visited = 0;
};

// Plain view of the octree. Node regions are implicit: the root covers 2^levels blocks per axis from
// the origin; split planes use BlockGrid::plane, i.e. exactly the occupancy tree's box coordinates.
struct SkipOctreeView {
  static constexpr std::uint32_t kNone = 0xFFFFFFFFu;
  const SkipOctreeNode* nodes = nullptr;
  ivec3 dims{0, 0, 0};  // volume, voxels
  vec3 spacing{1.0f};
  int block = 16;
  int levels = 0;

  // Requires t_end = the ray's volume exit and t < t_end; returns t1 > t (progress is guaranteed).
  // Descent compares split-plane crossings with the current [t, t_max] instead of locating the point
  // ray.at(t), so a ray exactly on a split plane goes to the side its direction leads into, and the
  // step's t1 is the leaf's exit (the slab test's value for the split plane) clipped to t_end.
  SL_HOST_DEVICE KdRestartStep step(const Ray& ray, float t, float t_end) const {
    KdRestartStep s;
    s.t0 = t;
    float t_max = t_end;
    std::uint32_t n = 0;
    ivec3 lo(0);                  // node origin, voxels
    int size = block << levels;   // node edge, voxels
    s.nodes_visited = 1;
    while (nodes[n].children != kNone) {
      size >>= 1;
      int octant = 0;
      for (int a = 0; a < 3; ++a) {
        const int mid_v = lo[a] + size;
        const float mid = float(mid_v) * spacing[a];  // == BlockGrid::plane(a, mid_v)
        const float o = ray.origin[a];
        const float d = ray.dir[a];
        bool upper;
        if (d == 0.0f) {
          upper = o >= mid;
        } else {
          const float inv = 1.0f / d;
          const float ts = (mid - o) * inv;  // the slab test's formula, bit for bit
          const bool near_is_lower = d > 0.0f;
          if (ts <= t) {
            upper = near_is_lower;   // plane at or behind t: we are on its far side
          } else {
            upper = !near_is_lower;  // still on the near side; the leaf ends at the plane at the latest
            t_max = ts < t_max ? ts : t_max;
          }
        }
        if (upper) {
          octant |= 1 << a;
          lo[a] += size;
        }
      }
      n = nodes[n].children + std::uint32_t(octant);
      ++s.nodes_visited;
    }
    s.t1 = t_max;
    s.cls = OccupancyClass(nodes[n].cls);
    return s;
  }
};

class SkipOctree {
 public:
  static constexpr std::uint32_t kNone = SkipOctreeView::kNone;
  // One class per block (block_index order); UNKNOWN is treated as NON_EMPTY.
  SkipOctree(const BlockGrid& grid, std::span<const OccupancyClass> block_classes);

  const std::vector<SkipOctreeNode>& nodes() const { return nodes_; }
  int levels() const { return levels_; }
  const BlockGrid& grid() const { return grid_; }
  SkipOctreeView view() const {
    return SkipOctreeView{nodes_.data(), grid_.dims, grid_.spacing, grid_.block, levels_};
  }
  // Leaf boxes clipped to the volume (wholly outside ones dropped) with their classes, for tests.
  struct Leaf {
    Box3 box;
    OccupancyClass cls;
  };
  std::vector<Leaf> leaves() const;

 private:
  std::uint8_t build(std::uint32_t node, ivec3 lo_block, int size_blocks,
                     std::span<const OccupancyClass> classes);

  BlockGrid grid_;
  int levels_ = 0;
  std::vector<SkipOctreeNode> nodes_;
};

}  // namespace sl
