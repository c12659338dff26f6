#include "core/occupancy/block_metadata.h"

#include "core/util/parallel.h"


#include <algorithm>
#include <atomic>
#include <iterator>
#include <limits>
#include <string>
#include <type_traits>

#include "core/util/error.h"

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

void dilated_block(ivec3 dims, ivec3 lo, int block, ivec3& first, ivec3& end) {
  first = glm::max(lo - 1, ivec3(0));
  end = glm::min(lo + block + 1, dims);  // exclusive
}

namespace {

// The range of `low` and `high` (T voxels) over [lo, hi), row by row with the type known: integer
// types are compared as integers and converted once; floats flag a NaN (it compares false both ways,
// so min/max alone would skip it).
template <class T>
void box_range(const VolumeView& low, const VolumeView& high, ivec3 lo, ivec3 hi, float& vmin, float& vmax,
               bool& nan) {
  const T* l = static_cast<const T*>(low.data);
  const T* h = static_cast<const T*>(high.data);
  const bool plain = l == h;
  T mn = l[low.index(lo.x, lo.y, lo.z)], mx = h[high.index(lo.x, lo.y, lo.z)];
  bool any_nan = false;
  for (int z = lo.z; z < hi.z; ++z) {
    for (int y = lo.y; y < hi.y; ++y) {
      const std::uint64_t row = low.index(0, y, z);
      const T* a = l + row;
      const T* b = plain ? a : h + row;
      for (int x = lo.x; x < hi.x; ++x) {
        mn = a[x] < mn ? a[x] : mn;
        mx = b[x] > mx ? b[x] : mx;
        if constexpr (std::is_floating_point_v<T>) any_nan = any_nan || a[x] != a[x] || b[x] != b[x];
      }
    }
  }
  vmin = float(mn);
  vmax = float(mx);
  nan = any_nan;  // the scan includes the first voxel, so a NaN anywhere is seen
}

// The ids of `labels` (T voxels) over [lo, hi), runs of one id listed once (sorted and made unique after).
template <class T> void box_labels(const VolumeView& labels, ivec3 lo, ivec3 hi, std::vector<std::uint32_t>& out) {
  const T* v = static_cast<const T*>(labels.data);
  std::uint32_t last = std::uint32_t(v[labels.index(lo.x, lo.y, lo.z)]);
  out.push_back(last);
  for (int z = lo.z; z < hi.z; ++z) {
    for (int y = lo.y; y < hi.y; ++y) {
      const T* row = v + labels.index(0, y, z);
      for (int x = lo.x; x < hi.x; ++x) {
        const std::uint32_t id = std::uint32_t(row[x]);
        if (id == last) continue;  // runs of one label are the common case
        last = id;
        out.push_back(id);
      }
    }
  }
}

}  // namespace

BlockMetadata compute_box_metadata(const VolumeView& low, const VolumeView& high, const VolumeView* labels,
                                   ivec3 lo, ivec3 hi) {
  ++g_computations;
  SL_CHECK(glm::all(glm::lessThan(lo, hi)) && glm::all(glm::greaterThanEqual(lo, ivec3(0))) &&
           glm::all(glm::lessThanEqual(hi, low.dims)));
  SL_CHECK(high.dims == low.dims && high.type == low.type && (!labels || labels->dims == low.dims));
  BlockMetadata m;
  m.computed = true;
  float vmin = 0.0f, vmax = 0.0f;
  bool nan = false;
  dispatch_voxel(low.type, [&](auto tag) { box_range<decltype(tag)>(low, high, lo, hi, vmin, vmax, nan); });
  // A NaN voxel makes every sample it touches NaN, which reads the transfer function's low end and
  // passes iso comparisons as "not below": the conservative range for such a block is everything.
  m.min = nan ? -std::numeric_limits<float>::infinity() : vmin;
  m.max = nan ? std::numeric_limits<float>::infinity() : vmax;
  if (labels) {
    m.has_labels = true;
    dispatch_voxel(labels->type, [&](auto tag) { box_labels<decltype(tag)>(*labels, lo, hi, m.labels); });
    std::sort(m.labels.begin(), m.labels.end());
    m.labels.erase(std::unique(m.labels.begin(), m.labels.end()), m.labels.end());
    m.labels.shrink_to_fit();
  }
  return m;
}

BlockMetadata compute_block_metadata(const VolumeView& intensity, const VolumeView* labels, ivec3 origin,
                                     ivec3 dims, ivec3 block_lo, int block) {
  ivec3 first, end;
  dilated_block(dims, block_lo, block, first, end);
  return compute_box_metadata(intensity, intensity, labels, first - origin, end - origin);
}

BlockMetadata compute_block_metadata(const BlockGrid& grid, const VolumeView& intensity,
                                     const VolumeView* labels, int bx, int by, int bz) {
  SL_CHECK(intensity.dims == grid.dims);
  SL_CHECK(grid.inside(ivec3(bx, by, bz)));
  return compute_block_metadata(intensity, labels, ivec3(0), grid.dims, ivec3(bx, by, bz) * grid.block, grid.block);
}

void merge_box_metadata(BlockMetadata& into, const BlockMetadata& more) {
  SL_CHECK(into.computed && more.computed && into.has_labels == more.has_labels);
  // (NaN ranges are the infinite ones, which min and max keep)
  into.min = std::min(into.min, more.min);
  into.max = std::max(into.max, more.max);
  if (!more.has_labels) return;
  std::vector<std::uint32_t> ids;
  ids.reserve(into.labels.size() + more.labels.size());
  std::set_union(into.labels.begin(), into.labels.end(), more.labels.begin(), more.labels.end(),
                 std::back_inserter(ids));
  into.labels = std::move(ids);
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

void widen_ranges_to_neighbours(BlockMetadataTable& table) {
  const BlockGrid& g = table.grid;
  // Separable: a min/max over {-1, 0, +1} along x, then y, then z is the min/max over the 27 blocks.
  for (int a = 0; a < 3; ++a) {
    std::vector<float> lo(table.blocks.size()), hi(table.blocks.size());
    for (std::size_t i = 0; i < table.blocks.size(); ++i) {
      lo[i] = table.blocks[i].min;
      hi[i] = table.blocks[i].max;
    }
    parallel_for(std::size_t(0), table.blocks.size(), [&](std::size_t i) {
      BlockMetadata& m = table.blocks[i];
      if (!m.computed) return;
      const ivec3 b = g.block_coord(i);
      for (int d = -1; d <= 1; d += 2) {
        ivec3 nb = b;
        nb[a] += d;
        if (nb[a] < 0 || nb[a] >= g.blocks[a]) continue;
        const std::size_t j = g.block_index(nb);
        if (!table.blocks[j].computed) continue;
        m.min = std::min(m.min, lo[j]);
        m.max = std::max(m.max, hi[j]);
      }
    });
  }
}

std::uint64_t block_metadata_computations() { return g_computations.load(); }

}  // namespace sl
