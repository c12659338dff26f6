// Culling blocks and their metadata (DESIGN.md "Data model", paper §9.1): intensity min/max over the block
// dilated by one voxel (the trilinear footprint of every point in the block) and the set of label ids
// present in that dilated region. Computed once per block; never recomputed for a transfer-function
// or label change (culling re-reads it, see core/occupancy/culling.h).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/util/config.h"
#include "core/util/math.h"
#include "core/util/ray.h"
#include "core/scene/volume.h"

namespace sl {

inline constexpr int kDefaultBlockSize = 16;

// Throws InputError("--block", ...) unless block is 4, 8, 16 or 32.
void validate_block_size(int block);

// The culling-block grid over a volume. Plain data.
struct BlockGrid {
  ivec3 dims{0, 0, 0};    // volume size in voxels
  int block = kDefaultBlockSize;
  ivec3 blocks{0, 0, 0};  // ceil(dims / block)
  vec3 spacing{1.0f};

  // World coordinate of voxel-grid plane v along axis a. Every box in the occupancy pipeline is made
  // with this one formula, so nested boxes that share a face share it bit for bit (and the slab test
  // then yields identical t for both, which the same-depth merge rules rely on).
  SL_HOST_DEVICE float plane(int a, int v) const { return float(v) * spacing[a]; }
  // World box of voxel-grid region [lo, hi) clipped to the volume.
  SL_HOST_DEVICE Box3 voxel_box(ivec3 lo, ivec3 hi) const {
    Box3 b;
    for (int a = 0; a < 3; ++a) {
      b.lo[a] = plane(a, lo[a] < dims[a] ? lo[a] : dims[a]);
      b.hi[a] = plane(a, hi[a] < dims[a] ? hi[a] : dims[a]);
    }
    return b;
  }
  // World box of block b; the last block along an axis is clipped to the volume.
  SL_HOST_DEVICE Box3 block_box(ivec3 b) const { return voxel_box(b * block, (b + 1) * block); }
  SL_HOST_DEVICE Box3 volume_box() const { return voxel_box(ivec3(0), dims); }
  SL_HOST_DEVICE std::size_t block_count() const {
    return std::size_t(blocks.x) * std::size_t(blocks.y) * std::size_t(blocks.z);
  }
  SL_HOST_DEVICE std::size_t block_index(ivec3 b) const {
    return (std::size_t(b.z) * std::size_t(blocks.y) + std::size_t(b.y)) * std::size_t(blocks.x) +
           std::size_t(b.x);
  }
  SL_HOST_DEVICE ivec3 block_coord(std::size_t i) const {
    const std::size_t bx = std::size_t(blocks.x), bxy = bx * std::size_t(blocks.y);
    return ivec3(int(i % bx), int((i / bx) % std::size_t(blocks.y)), int(i / bxy));
  }
  SL_HOST_DEVICE bool inside(ivec3 b) const {
    return b.x >= 0 && b.y >= 0 && b.z >= 0 && b.x < blocks.x && b.y < blocks.y && b.z < blocks.z;
  }
};

// Validates the block size (InputError "--block") and the dims (positive).
BlockGrid make_block_grid(ivec3 dims, vec3 spacing, int block = kDefaultBlockSize);

struct BlockMetadata {
  float min = 0.0f;  // intensity range over the block dilated by one voxel, clamped to the volume
  float max = 0.0f;
  // The ids present are listed: a label volume was given and its ids below the block are known (a
  // source that cannot list them for a coarse block leaves this false: no culling by labels there).
  bool has_labels = false;
  std::vector<std::uint32_t> labels;  // ids present in the dilated block, ascending, unique (incl. 0)
  bool computed = false;              // false: not yet computed (the lazy out-of-core path)
};

// The voxels a culling block's metadata covers: the block of edge `block` whose first voxel is `lo`,
// in a volume (or pyramid level) of `dims` voxels, dilated by one voxel and clamped: [first, end).
// A trilinear sample anywhere in the block's world box reads voxels floor(p / spacing - 0.5) and that
// + 1, i.e. [lo - 1, lo + block] per axis (clamped); a nearest-voxel label lookup floor(p / spacing)
// stays within the same range even with rounding at the faces.
void dilated_block(ivec3 dims, ivec3 lo, int block, ivec3& first, ivec3& end);

// The metadata of the voxels [first, end) of the views' own coordinates: the least value of `low`,
// the largest of `high` (the same view for plain data; a min and a max pyramid level where a coarse
// block must bound every finer voxel below it, DESIGN.md "Virtual memory") and the ids present in `labels` (null:
// none). The views share dims and must cover the box. Counts one computation.
BlockMetadata compute_box_metadata(const VolumeView& low, const VolumeView& high, const VolumeView* labels,
                                   ivec3 first, ivec3 end);

// The metadata of two boxes' union: `into` widened by `more` (ranges and label sets; both computed,
// both listing labels or neither). What compute_box_metadata gives for a box, merged from a cover of
// it by parts, equals what it gives for the whole.
void merge_box_metadata(BlockMetadata& into, const BlockMetadata& more);

// A culling block's metadata from its own voxels, in core and out of core: the block of edge
// `block` whose first voxel is `lo`, in a volume (or pyramid level) of `dims` voxels, dilated by one
// voxel and clamped to the volume (dilated_block). The views hold the voxels from volume voxel
// `origin` on: the whole volume in core (origin 0), a brick with its apron out of core (origin = the
// apron's first voxel); they must cover the dilated block. `labels` may be null (no label volume).
// Counts one computation.
BlockMetadata compute_block_metadata(const VolumeView& intensity, const VolumeView* labels, ivec3 origin,
                                     ivec3 dims, ivec3 lo, int block);

// Metadata of block (bx, by, bz) of a whole volume held in `intensity` (and `labels`).
BlockMetadata compute_block_metadata(const BlockGrid& grid, const VolumeView& intensity,
                                     const VolumeView* labels, int bx, int by, int bz);

struct BlockMetadataTable {
  BlockGrid grid;
  std::vector<BlockMetadata> blocks;  // block_index order (x fastest)

  const BlockMetadata& at(ivec3 b) const { return blocks[grid.block_index(b)]; }
  BlockMetadata& at(ivec3 b) { return blocks[grid.block_index(b)]; }
};

// All blocks, in parallel (TBB). Deterministic.
BlockMetadataTable compute_all_block_metadata(const BlockGrid& grid, const VolumeView& intensity,
                                              const VolumeView* labels);

// Widens every block's intensity range to the union of the ranges of its 26 neighbours and itself, for
// a reconstruction filter wider than trilinear (the B-splines of core/recon/bspline.h read one voxel more on
// each side than the one-voxel dilation covers; a neighbouring block, at least one voxel deep, dilated by
// one, covers that voxel). The label sets stay: labels are looked up nearest-voxel whatever the filter.
// Blocks not yet computed are left as they are (in core every block is computed).
void widen_ranges_to_neighbours(BlockMetadataTable& table);

// Number of compute_block_metadata calls so far in this process, in core and out of core (tests prove
// that re-culling for a transfer-function or label change does not recompute metadata).
std::uint64_t block_metadata_computations();

}  // namespace sl
