// Sort-last distributed rendering (DESIGN.md "Beyond one machine"): the volume's brick grid split by a k-d tree into
// one convex, brick-aligned region per rank, balanced on the estimated work, and the regions' front-
// to-back order for a view (what IceT composites in, icetCompositeOrder). Pure logic, no MPI, so the
// tests run it without mpirun.
#pragma once

#include <cstddef>
#include <vector>

#include "core/util/math.h"
#include "core/util/ray.h"
#include "core/cast/sample_clip.h"
#include "core/lists/visibility_order.h"

namespace sl {

// Estimated work over a grid of cells, each `cell` level-0 voxels on a side (a brick of a coarse
// level, so every cell boundary is a brick and culling-block boundary at level 0).
struct WorkGrid {
  ivec3 dims{0};           // volume size in level-0 voxels
  vec3 spacing{1.0f};
  int cell = 32;           // cell edge in level-0 voxels
  ivec3 cells{0};          // ceil(dims / cell)
  std::vector<double> work;  // per cell, x fastest

  std::size_t index(ivec3 c) const {
    return (std::size_t(c.z) * std::size_t(cells.y) + std::size_t(c.y)) * std::size_t(cells.x) + std::size_t(c.x);
  }
  // World coordinate of cell boundary i along axis a (the BlockGrid::plane formula on the voxel
  // index, clamped to the volume): regions and the occupancy boxes share their faces bit for bit.
  float plane(int a, int i) const;
};

// An empty grid of the volume's cells (work all zero).
WorkGrid make_work_grid(ivec3 dims, vec3 spacing, int cell);

struct KdRegion {
  ivec3 lo{0}, hi{0};  // cells [lo, hi); empty along an axis when lo == hi (a rank with no region)
  double work = 0.0;   // estimated work inside
  SampleClip clip;     // the samples it owns: half-open, faces on the volume's boundary at infinity
  Box3 box;            // world box, clamped to the volume (empty region: lo == hi)
  bool empty() const { return lo.x >= hi.x || lo.y >= hi.y || lo.z >= hi.z; }
};

struct KdSplit {
  struct Node {
    int axis = 0;
    float plane = 0.0f;       // world coordinate of the split
    int left = 0, right = 0;  // >= 0: node index; < 0: region -1 - value (the lower side is `left`)
  };
  std::vector<KdRegion> regions;  // one per rank, in rank order
  std::vector<Node> nodes;        // nodes[0] is the root; none for a single region

  // The regions front to back for the view: at each split the side holding the eye (perspective) or
  // the side the view direction leaves first (orthographic) comes first; a ray crosses a split plane
  // at most once and only in that direction, so each ray meets the regions in this order.
  std::vector<int> order(const ViewPoint& view) const;
  double max_over_mean_work() const;  // load imbalance of the estimate (1: perfect)
};

// Splits `grid` into `ranks` regions (ranks >= 1): recursively, ranks as n/2 and n - n/2, at the cell
// boundary (any axis) that best balances the work per rank of the two halves (ties: the longer axis,
// then the boundary nearest the proportional position, so zero work splits geometrically). A box of
// one cell gives its remaining ranks empty regions.
KdSplit split_regions(const WorkGrid& grid, int ranks);

}  // namespace sl
