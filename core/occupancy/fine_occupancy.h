// Fine-grained occupancy inside non-empty segments (DESIGN.md "Ray casting"): one bit per cell of C³ voxels
// (C = 4 or 8), set when some sample in the cell can contribute under the current transfer function
// and labels. The caster walks the cells of a sampled span and skips the grid samples of clear cells;
// the samples it takes stay on the one global grid t_k = t_entry + k·dt, so the image is exactly the
// one without the grid — only the number of samples drops.
//
// Why skipping a clear cell is exact: a cell's bit comes from the same culling test as a culling block
// (core/occupancy/culling.h) over metadata of the cell dilated by one voxel. A sample at world point p reads the
// voxels floor(p / spacing − 0.5) and +1 (trilinear) and the label of voxel floor(p / spacing); for
// every p within half a voxel of the cell's box these lie in the dilated cell, so the half-voxel margin
// absorbs any rounding in the cell index or the exit distance computed below.
//
// Plain data (a pointer to bits and the grid's geometry): the CUDA kernels read the same view.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/util/config.h"
#include "core/util/math.h"
#include "core/util/ray.h"
#include "core/occupancy/culling.h"
#include "core/recon/sampling.h"
#include "core/scene/volume.h"

namespace sl {

// The finest level: a bit per trilinear cell (the 2×2×2 voxels one sample blends), set when a sample
// in it can contribute under the current transfer function and labels (DVR and labels modes, the
// trilinear filter, level 0 of an in-core u8/u16 volume). The caster tests it before it fetches a
// sample: the cell is the one DenseGrid::sample blends (clamped_voxel_coord, the same arithmetic), so a
// clear bit is exact — its 8 voxels' range is fully transparent, or none of their labels is enabled,
// and the sample's value lies in that range and its label is one of them. Cell (x, y, z) has bit x
// of row (z, y); rows are padded to whole 64-bit words.
struct VoxelMaskView {
  const std::uint64_t* bits = nullptr;  // null: no mask (every sample is fetched)
  ivec3 dims{0, 0, 0};                  // the volume's (and the cells') dims
  int row_words = 0;                    // 64-bit words per row of cells: (dims.x + 63) / 64
  int plane_words = 0;                  // per z-plane of cells: row_words * dims.y
  vec3 inv_spacing{1.0f};
  vec3 max_coord{0.0f};                 // vec3(dims - 1), for clamped_voxel_coord
  // The share of the trilinear cells inside the occupied fine cells whose bit is set (0: not measured).
  // Only the CPU's batched march reads it, to choose how it finds the set bits (core/cast/raycast_batch.inc);
  // it fills what would be padding, so the device layout stays as it was.
  float fill = 0.0f;

  SL_HOST_DEVICE SL_INLINE bool enabled() const { return bits != nullptr; }
  SL_HOST_DEVICE std::size_t word_count() const {
    return std::size_t(row_words) * std::size_t(dims.y) * std::size_t(dims.z);
  }
  // The bit of the trilinear cell holding world point p.
  SL_HOST_DEVICE SL_INLINE bool visible(const vec3& p) const { return visible_coord(coord(p)); }
  // The same in two steps: the sample's clamped voxel coordinate (which DenseGrid::sample_coord
  // blends from, when the mask was built from that grid's volume), and its cell's bit.
  SL_HOST_DEVICE SL_INLINE vec3 coord(const vec3& p) const { return clamped_voxel_coord(p, inv_spacing, max_coord); }
  SL_HOST_DEVICE SL_INLINE bool visible_coord(const vec3& u) const {
    const int x = int(u.x), y = int(u.y), z = int(u.z);
    const std::int64_t w = std::int64_t(z) * plane_words + std::int64_t(y * row_words + (x >> 6));
    return ((bits[w] >> (x & 63)) & 1u) != 0u;
  }
};
static_assert(sizeof(VoxelMaskView) == 56, "VoxelMaskView is uploaded to devices as is");

struct FineOccupancyView {
  const std::uint64_t* bits = nullptr;  // null: no fine grid (every cell counts as occupied)
  ivec3 cells{0, 0, 0};
  vec3 cell_size{1.0f};                 // world size of a cell: C * spacing
  vec3 inv_cell_size{1.0f};
  VoxelMaskView voxels;                 // inside occupied cells, the per-sample test (off: not built)

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

  SL_HOST_DEVICE SL_INLINE std::int64_t linear_index(const ivec3& c) const {
    return (std::int64_t(c.z) * cells.y + c.y) * std::int64_t(cells.x) + c.x;
  }
  SL_HOST_DEVICE SL_INLINE bool occupied_at(std::int64_t i) const {
    return ((bits[std::size_t(i) >> 6] >> (std::size_t(i) & 63u)) & 1u) != 0u;
  }
  SL_HOST_DEVICE SL_INLINE bool occupied(const ivec3& c) const { return occupied_at(linear_index(c)); }

  SL_HOST_DEVICE SL_INLINE static vec3 inverse_direction(const Ray& r) {
    vec3 inv;
    for (int a = 0; a < 3; ++a) inv[a] = r.dir[a] != 0.0f ? 1.0f / r.dir[a] : 0.0f;
    return inv;
  }
};
static_assert(sizeof(FineOccupancyView) == 104, "FineOccupancyView is uploaded to devices as is");

// The cells a ray crosses, in order: a 3D DDA (Amanatides & Woo 1987) that steps to the neighbour
// across the nearest exit plane, so a cell costs a comparison and one plane distance instead of a
// cell lookup per sample. Each exit distance is computed from its plane (never accumulated): its
// rounding is one ulp-sized error, far inside the half-voxel margin that makes skipping exact. The
// walk starts at the cell holding a point of the ray (clamped to the grid) and ends when it would
// leave the grid; the caster then samples the rest of its span without skipping.
struct FineCellWalk {
  ivec3 cell;
  ivec3 step;          // +1 / -1 per axis (0: the ray runs parallel to it)
  std::int64_t index;  // linear index of `cell`
  vec3 t_exit;         // ray parameter of the exit plane per axis (the largest float where step is 0)
  vec3 inv_dir;
  std::int64_t step_y, step_z;  // change of `index` for a step in y and in z

  SL_HOST_DEVICE SL_INLINE FineCellWalk(const FineOccupancyView& f, const Ray& r, const vec3& p)
      : cell(f.cell_of(p)), index(f.linear_index(cell)), inv_dir(FineOccupancyView::inverse_direction(r)) {
    for (int a = 0; a < 3; ++a) {
      step[a] = inv_dir[a] > 0.0f ? 1 : (inv_dir[a] < 0.0f ? -1 : 0);
      t_exit[a] = plane_t(float(step[a] > 0 ? cell[a] + 1 : cell[a]) * f.cell_size[a], r.origin[a], inv_dir[a]);
    }
    step_y = step.y * std::int64_t(f.cells.x);
    step_z = step.z * std::int64_t(f.cells.x) * f.cells.y;
  }

  // Where the ray leaves the current cell.
  SL_HOST_DEVICE SL_INLINE float exit() const {
    const float t = t_exit.x < t_exit.y ? t_exit.x : t_exit.y;
    return t < t_exit.z ? t : t_exit.z;
  }

  // Moves to the next cell along the ray; false when that cell lies outside the grid. The axes are
  // spelled out (no indexing by a run-time axis): the walk's state then stays in registers.
  SL_HOST_DEVICE SL_INLINE bool advance(const FineOccupancyView& f, const Ray& r) {
    if (t_exit.x <= t_exit.y && t_exit.x <= t_exit.z) {
      if (step.x == 0) return false;  // every exit is "never": the ray does not leave the cell
      cell.x += step.x;
      if (cell.x < 0 || cell.x >= f.cells.x) return false;
      index += step.x;
      t_exit.x = plane_t(float(step.x > 0 ? cell.x + 1 : cell.x) * f.cell_size.x, r.origin.x, inv_dir.x);
    } else if (t_exit.y <= t_exit.z) {
      if (step.y == 0) return false;
      cell.y += step.y;
      if (cell.y < 0 || cell.y >= f.cells.y) return false;
      index += step_y;
      t_exit.y = plane_t(float(step.y > 0 ? cell.y + 1 : cell.y) * f.cell_size.y, r.origin.y, inv_dir.y);
    } else {
      if (step.z == 0) return false;
      cell.z += step.z;
      if (cell.z < 0 || cell.z >= f.cells.z) return false;
      index += step_z;
      t_exit.z = plane_t(float(step.z > 0 ? cell.z + 1 : cell.z) * f.cell_size.z, r.origin.z, inv_dir.z);
    }
    return true;
  }

 private:
  // Where the ray meets an exit plane (the expression FineOccupancyView used per cell); "never"
  // (the largest float) on an axis the ray runs parallel to.
  SL_HOST_DEVICE SL_INLINE static float plane_t(float plane, float origin, float inv) {
    return inv != 0.0f ? (plane - origin) * inv : 3.402823466e+38f;
  }
};

// The voxel mask's rule for one culling input: the bits of the trilinear cells of a dense u8/u16 block
// of voxels (a whole volume, or one brick's stored voxels out of core), cell (x, y, z) anchored at voxel
// (x, y, z) and reading its +1 neighbours (clamped at the block's last voxel). Holds the transfer
// function's opacity reach, worked out once per culling input.
class VoxelMaskBuilder {
 public:
  // cull.mode must be Dvr or Labels and `type` u8 or u16 (std::logic_error otherwise).
  VoxelMaskBuilder(VoxelType type, const CullParams& cull);
  // Sets the bits of `volume`'s cells into `bits` (zeroed by the caller; rows of `row_words` words,
  // planes of row_words * dims.y) and returns how many are set. `labels` as VoxelMask::build.
  std::size_t build(const VolumeView& volume, const VolumeView* labels, int row_words, std::uint64_t* bits,
                    bool parallel) const;

 private:
  VoxelType type_;
  CullParams cull_;
  std::vector<std::uint32_t> reach_;
};

// The host side of VoxelMaskView: built from the volume (and labels) for the current culling
// parameters, one pass over the voxels (parallel over rows); u8 and u16 volumes only (supported()).
class VoxelMask {
 public:
  static bool supported(const VolumeView& volume);
  // cull.mode must be Dvr or Labels. Throws std::logic_error for an unsupported volume type.
  void build(const VolumeView& volume, const VolumeView* labels, const CullParams& cull);
  VoxelMaskView view() const { return view_; }
  std::size_t set_cells() const { return set_; }
  std::size_t bytes() const { return bits_.size() * sizeof(std::uint64_t); }

 private:
  std::vector<std::uint64_t> bits_;
  VoxelMaskView view_;
  std::size_t set_ = 0;
};

// Allowed cell edges in voxels, and the default: kFineCellAuto, which resolve_fine_cell turns into 8 where the
// voxel mask is built (the mask then culls sample by sample, and the walk crosses half as many cells, for fewer
// instructions per frame than 4³ at the same samples) and into 4 elsewhere (there the cell alone culls, and smaller
// cells skip more).
inline constexpr int kFineCellAuto = -1;
inline constexpr int kDefaultFineCell = kFineCellAuto;
// Throws InputError("--fine-cell", ...) unless cell is kFineCellAuto, 0 (off), 4 or 8.
void validate_fine_cell(int cell);
// The cell edge `cell` (validated) means when the voxel mask is (or is not) built inside the cells.
inline int resolve_fine_cell(int cell, bool voxel_mask) { return cell == kFineCellAuto ? (voxel_mask ? 8 : 4) : cell; }

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
