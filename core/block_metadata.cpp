#include "core/block_metadata.h"

#include "core/parallel.h"


#include <algorithm>
#include <limits>
#include <atomic>
#include <string>

#include "core/error.h"

namespace sl {

namespace {
std::atomic<std::uint64_t> g_computations{0};
}  // namespace

void validate_block_size(int block) {
  if (block != 4 && block != 8 && block != 16 && block != 32) {
    throw InputError("--block", "culling block size must be 4, 8, 16 or 32 (got " + std::to_string(block) + ")");
  }
}

BlockGrid make_block_grid(ivec3 dims, vec3 spacing, int block) {
  validate_block_size(block);
  SL_CHECK(dims.x > 0 && dims.y > 0 && dims.z > 0);
  SL_CHECK(spacing.x > 0.0f && spacing.y > 0.0f && spacing.z > 0.0f);
  BlockGrid g;
  g.dims = dims;
  g.block = block;
  g.blocks = (dims + block - 1) / block;
  g.spacing = spacing;
  return g;
}

BlockMetadata compute_block_metadata(const VolumeView& intensity, const VolumeView* labels, ivec3 origin,
                                     ivec3 dims, ivec3 block_lo, int block) {
  ++g_computations;
  // Dilated by one voxel: a trilinear sample anywhere in the block's world box reads voxels
  // floor(p / spacing - 0.5) and that + 1, i.e. [lo - 1, lo + block] per axis (clamped); a
  // nearest-voxel label lookup floor(p / spacing) stays within the same range even with rounding at
  // the faces. Below, in the views' own coordinates.
  const ivec3 lo = glm::max(block_lo - 1, ivec3(0)) - origin;
  const ivec3 hi = glm::min(block_lo + block + 1, dims) - origin;  // exclusive
  SL_CHECK(glm::all(glm::lessThan(lo, hi)) && glm::all(glm::greaterThanEqual(lo, ivec3(0))) &&
           glm::all(glm::lessThanEqual(hi, intensity.dims)));
  SL_CHECK(!labels || labels->dims == intensity.dims);
  BlockMetadata m;
  m.computed = true;
  float vmin = intensity.value(lo.x, lo.y, lo.z);
  float vmax = vmin;
  bool nan = false;  // float volumes: NaN compares false both ways, so min/max alone would skip it
  for (int z = lo.z; z < hi.z; ++z) {
    for (int y = lo.y; y < hi.y; ++y) {
      for (int x = lo.x; x < hi.x; ++x) {
        const float v = intensity.value(x, y, z);
        vmin = v < vmin ? v : vmin;
        vmax = v > vmax ? v : vmax;
        nan = nan || v != v;
      }
    }
  }
  // A NaN voxel makes every sample it touches NaN, which reads the transfer function's low end and
  // passes iso comparisons as "not below": the conservative range for such a block is everything.
  m.min = nan ? -std::numeric_limits<float>::infinity() : vmin;
  m.max = nan ? std::numeric_limits<float>::infinity() : vmax;
  if (labels) {
    m.has_labels = true;
    std::uint32_t last = labels->label(lo.x, lo.y, lo.z);
    m.labels.push_back(last);
    for (int z = lo.z; z < hi.z; ++z) {
      for (int y = lo.y; y < hi.y; ++y) {
        for (int x = lo.x; x < hi.x; ++x) {
          const std::uint32_t id = labels->label(x, y, z);
          if (id == last) continue;  // runs of one label are the common case
          last = id;
          m.labels.push_back(id);
        }
      }
    }
    std::sort(m.labels.begin(), m.labels.end());
    m.labels.erase(std::unique(m.labels.begin(), m.labels.end()), m.labels.end());
    m.labels.shrink_to_fit();
  }
  return m;
}

BlockMetadata compute_block_metadata(const BlockGrid& grid, const VolumeView& intensity,
                                     const VolumeView* labels, int bx, int by, int bz) {
  SL_CHECK(intensity.dims == grid.dims);
  SL_CHECK(grid.inside(ivec3(bx, by, bz)));
  return compute_block_metadata(intensity, labels, ivec3(0), grid.dims, ivec3(bx, by, bz) * grid.block, grid.block);
}

BlockMetadataTable compute_all_block_metadata(const BlockGrid& grid, const VolumeView& intensity,
                                              const VolumeView* labels) {
  BlockMetadataTable t;
  t.grid = grid;
  t.blocks.resize(grid.block_count());
  parallel_for(std::size_t(0), t.blocks.size(), [&](std::size_t i) {
    const ivec3 b = grid.block_coord(i);
    t.blocks[i] = compute_block_metadata(grid, intensity, labels, b.x, b.y, b.z);
  });
  return t;
}

std::uint64_t block_metadata_computations() { return g_computations.load(); }

}  // namespace sl
