// Fine-grained occupancy inside non-empty segments (DESIGN.md §8): one bit per cell of C³ voxels
// (C = 4 or 8), set when some sample in the cell can contribute under the current transfer function
// and labels. The caster walks the cells of a sampled span and skips the grid samples of clear cells;
// the samples it takes stay on the one global grid t_k = t_entry + k·dt, so the image is exactly the
// one without the grid — only the number of samples drops.
//
// Why skipping a clear cell is exact: a cell's bit comes from the same culling test as a culling block
// (core/culling.h) over metadata of the cell dilated by one voxel. A sample at world point p reads the
// voxels floor(p / spacing − 0.5) and +1 (trilinear) and the label of voxel floor(p / spacing); for
// every p within half a voxel of the cell's box these lie in the dilated cell, so the half-voxel margin
// absorbs any rounding in the cell index or the exit distance computed below.
//
// Plain data (a pointer to bits and the grid's geometry): the CUDA kernels read the same view.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/config.h"
#include "core/math.h"
#include "core/ray.h"

namespace sl {

struct BlockMetadataTable;
struct CullParams;

struct FineOccupancyView {
  const std::uint64_t* bits = nullptr;  // null: no fine grid (every cell counts as occupied)
  ivec3 cells{0, 0, 0};
  vec3 cell_size{1.0f};                 // world size of a cell: C * spacing
  vec3 inv_cell_size{1.0f};

  SL_HOST_DEVICE SL_INLINE bool enabled() const { return bits != nullptr; }
  // 64-bit words behind `bits` (what a device copy must hold).
  SL_HOST_DEVICE std::size_t word_count() const {
    return (std::size_t(cells.x) * std::size_t(cells.y) * std::size_t(cells.z) + 63) / 64;
  }

  // The cell holding p, clamped to the grid. Truncation equals floor here: a negative coordinate
  // above −1 truncates to 0, which is what the clamp makes of floor's −1.
  SL_HOST_DEVICE SL_INLINE ivec3 cell_of(const vec3& p) const {
    const vec3 u = p * inv_cell_size;
    int x = int(u.x), y = int(u.y), z = int(u.z);
    x = x < 0 ? 0 : (x >= cells.x ? cells.x - 1 : x);
    y = y < 0 ? 0 : (y >= cells.y ? cells.y - 1 : y);
    z = z < 0 ? 0 : (z >= cells.z ? cells.z - 1 : z);
    return ivec3(x, y, z);
  }

  SL_HOST_DEVICE SL_INLINE bool occupied(const ivec3& c) const {
    const std::size_t i =
        (std::size_t(c.z) * std::size_t(cells.y) + std::size_t(c.y)) * std::size_t(cells.x) + std::size_t(c.x);
    return ((bits[i >> 6] >> (i & 63u)) & 1u) != 0u;
  }

  // Where the ray leaves cell c: the nearest exit plane over the three axes. `inv_dir` holds 1 / dir
  // per axis, or 0 where the ray runs parallel to it (such an axis never ends the cell). The rounding
  // of the reciprocal moves the exit by an ulp: far inside the half-voxel margin.
  SL_HOST_DEVICE SL_INLINE float cell_exit(const Ray& r, const vec3& inv_dir, const ivec3& c) const {
    float t = 3.402823466e+38f;
    for (int a = 0; a < 3; ++a) {
      if (inv_dir[a] == 0.0f) continue;
      const float plane = float(inv_dir[a] > 0.0f ? c[a] + 1 : c[a]) * cell_size[a];
      const float ta = (plane - r.origin[a]) * inv_dir[a];
      t = ta < t ? ta : t;
    }
    return t;
  }

  SL_HOST_DEVICE SL_INLINE static vec3 inverse_direction(const Ray& r) {
    vec3 inv;
    for (int a = 0; a < 3; ++a) inv[a] = r.dir[a] != 0.0f ? 1.0f / r.dir[a] : 0.0f;
    return inv;
  }
};
static_assert(sizeof(FineOccupancyView) == 48, "FineOccupancyView is uploaded to devices as is");

// Allowed cell edges in voxels.
inline constexpr int kDefaultFineCell = 4;
// Throws InputError("--fine-cell", ...) unless cell is 0 (off), 4 or 8.
void validate_fine_cell(int cell);

// The host side: per-cell metadata (computed once per volume, like the culling blocks') and the bits
// derived from it for the current culling parameters (recomputed for a transfer-function or label
// change without touching the volume).
class FineOccupancy {
 public:
  // Sets the bits from `metadata` (a block table whose blocks are the cells) under `cull`: a bit is set
  // unless classify_block says EMPTY. Deterministic, parallel over cells.
  void classify(const BlockMetadataTable& metadata, const CullParams& cull);

  FineOccupancyView view() const { return view_; }
  std::size_t set_cells() const { return set_; }
  std::size_t cell_count() const {
    return std::size_t(view_.cells.x) * std::size_t(view_.cells.y) * std::size_t(view_.cells.z);
  }

 private:
  std::vector<std::uint64_t> bits_;
  FineOccupancyView view_;
  std::size_t set_ = 0;
};

}  // namespace sl
