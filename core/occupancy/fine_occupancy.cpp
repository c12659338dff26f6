#include "core/occupancy/fine_occupancy.h"

#include <algorithm>
#include <atomic>
#include <bit>
#include <stdexcept>
#include <string>

#include "core/occupancy/block_metadata.h"
#include "core/occupancy/culling.h"
#include "core/util/error.h"
#include "core/scene/labels.h"
#include "core/util/parallel.h"
#include "core/scene/transfer_function.h"
#include "core/scene/volume.h"

namespace sl {

void validate_fine_cell(int cell) {
  if (cell != kFineCellAuto && cell != 0 && cell != 4 && cell != 8) {
    throw InputError("--fine-cell",
                     "fine occupancy cell must be auto, 0 (off), 4 or 8 voxels, not " + std::to_string(cell));
  }
}

void FineOccupancy::classify(const BlockMetadataTable& metadata, const CullParams& cull) {
  const BlockGrid& g = metadata.grid;
  // The same test as a culling block's (core/occupancy/culling.h), so a clear bit is as conservative as EMPTY.
  const std::vector<OccupancyClass> classes = classify_blocks(metadata, cull);
  bits_.assign((classes.size() + 63) / 64, 0u);
  set_ = 0;
  for (std::size_t i = 0; i < classes.size(); ++i) {
    if (classes[i] != OccupancyClass::Empty) bits_[i >> 6] |= std::uint64_t(1) << (i & 63u);
  }
  for (const std::uint64_t w : bits_) set_ += std::size_t(std::popcount(w));
  view_.bits = bits_.data();
  view_.cells = g.blocks;
  view_.cell_size = vec3(float(g.block)) * g.spacing;
  view_.inv_cell_size = 1.0f / view_.cell_size;
}

namespace {

// reach[a]: the smallest integer b >= a with max_opacity(a, b) > 0 (n where there is none), so that
// [lo, hi] is visible exactly when hi >= reach[lo] — the test classify_block makes of a block's range,
// answered per cell by one load. max_opacity(a, b) grows with b and shrinks with a ([a', b] lies in
// [a, b] for a' > a), so reach does not decrease and one sweep finds it. No transfer function: every
// range is visible.
std::vector<std::uint32_t> opacity_reach(const TransferFunction* tf, std::uint32_t n) {
  std::vector<std::uint32_t> reach(n);
  std::uint32_t b = 0;
  for (std::uint32_t a = 0; a < n; ++a) {
    if (b < a) b = a;
    while (tf && b < n && !(tf->max_opacity(float(a), float(b)) > 0.0f)) ++b;
    reach[a] = b;
  }
  return reach;
}

// Rows of cells, bits of row (z, y) from voxel rows (z, y), (z, y + 1), (z + 1, y), (z + 1, y + 1)
// (the +1 clamped at the last voxel, as DenseGrid::sample clamps): per x the min, max and "some label
// enabled" of the four rows, then of x and x + 1.
template <class T, class L>
std::size_t build_mask(const T* data, const L* labels, const ivec3& d, const std::vector<std::uint32_t>& reach,
                       const LabelSet* enabled, int row_words, std::uint64_t* bits, bool parallel) {
  std::atomic<std::size_t> set{0};
  const auto plane = [&](int z) {
    std::vector<T> mn(std::size_t(d.x)), mx(std::size_t(d.x));
    std::vector<std::uint8_t> on(std::size_t(d.x), 1);
    const std::size_t sx = std::size_t(d.x), sxy = sx * std::size_t(d.y);
    const std::size_t z1 = std::size_t(z + 1 < d.z ? z + 1 : z);
    std::size_t count = 0;
    for (int y = 0; y < d.y; ++y) {
      const std::size_t y1 = std::size_t(y + 1 < d.y ? y + 1 : y);
      const std::size_t rows[4] = {std::size_t(z) * sxy + std::size_t(y) * sx, std::size_t(z) * sxy + y1 * sx,
                                   z1 * sxy + std::size_t(y) * sx, z1 * sxy + y1 * sx};
      for (int x = 0; x < d.x; ++x) {
        T lo = data[rows[0] + std::size_t(x)], hi = lo;
        for (int r = 1; r < 4; ++r) {
          const T v = data[rows[r] + std::size_t(x)];
          lo = v < lo ? v : lo;
          hi = v > hi ? v : hi;
        }
        mn[std::size_t(x)] = lo;
        mx[std::size_t(x)] = hi;
        if (labels) {
          bool any = false;
          for (int r = 0; r < 4; ++r) any = any || enabled->enabled(std::uint32_t(labels[rows[r] + std::size_t(x)]));
          on[std::size_t(x)] = any ? 1 : 0;
        }
      }
      std::uint64_t* row = bits + (std::size_t(z) * std::size_t(d.y) + std::size_t(y)) * std::size_t(row_words);
      for (int x = 0; x < d.x; ++x) {
        const std::size_t x1 = std::size_t(x + 1 < d.x ? x + 1 : x);
        const T lo = std::min(mn[std::size_t(x)], mn[x1]), hi = std::max(mx[std::size_t(x)], mx[x1]);
        const bool label_ok = !labels || on[std::size_t(x)] || on[x1];
        if (label_ok && std::uint32_t(hi) >= reach[lo]) {
          row[x >> 6] |= std::uint64_t(1) << (x & 63);
          ++count;
        }
      }
    }
    set += count;
  };
  if (parallel) {
    parallel_for(0, d.z, plane);
  } else {
    for (int z = 0; z < d.z; ++z) plane(z);
  }
  return set.load();
}

}  // namespace

bool VoxelMask::supported(const VolumeView& volume) {
  return volume.type == VoxelType::U8 || volume.type == VoxelType::U16;
}

VoxelMaskBuilder::VoxelMaskBuilder(VoxelType type, const CullParams& cull)
    : type_(type), cull_(cull), reach_(opacity_reach(cull.tf, type == VoxelType::U8 ? 256u : 65536u)) {
  if (type != VoxelType::U8 && type != VoxelType::U16) throw std::logic_error("VoxelMask: u8 and u16 volumes only");
  if (cull.mode != RenderMode::Dvr && cull.mode != RenderMode::Labels) {
    throw std::logic_error("VoxelMask: DVR and labels modes only");
  }
}

std::size_t VoxelMaskBuilder::build(const VolumeView& volume, const VolumeView* labels, int row_words,
                                    std::uint64_t* bits, bool parallel) const {
  SL_CHECK(volume.type == type_);
  // The label test of classify_block: only with an enabled set and a label volume.
  const VolumeView* lv = cull_.enabled && labels && labels->data ? labels : nullptr;
  std::size_t set = 0;
  dispatch_voxel(volume.type, [&](auto vtag) {
    using T = decltype(vtag);
    if constexpr (std::is_same_v<T, std::uint8_t> || std::is_same_v<T, std::uint16_t>) {
      const T* data = static_cast<const T*>(volume.data);
      if (!lv) {
        set = build_mask<T, std::uint8_t>(data, nullptr, volume.dims, reach_, nullptr, row_words, bits, parallel);
        return;
      }
      dispatch_label(
          lv->type,
          [&](auto ltag) {
            using L = decltype(ltag);
            set = build_mask<T, L>(data, static_cast<const L*>(lv->data), volume.dims, reach_, cull_.enabled,
                                   row_words, bits, parallel);
          },
          [] { throw std::logic_error("VoxelMask: label volume of a float type"); });
    }
  });
  return set;
}

void VoxelMask::build(const VolumeView& volume, const VolumeView* labels, const CullParams& cull) {
  if (!supported(volume)) throw std::logic_error("VoxelMask: u8 and u16 volumes only");
  const VoxelMaskBuilder builder(volume.type, cull);
  const ivec3 d = volume.dims;
  view_ = VoxelMaskView{};
  view_.dims = d;
  view_.row_words = (d.x + 63) / 64;
  view_.plane_words = view_.row_words * d.y;
  view_.inv_spacing = 1.0f / volume.spacing;
  view_.max_coord = vec3(d - 1);
  bits_.assign(view_.word_count(), 0u);
  set_ = builder.build(volume, labels, view_.row_words, bits_.data(), /*parallel=*/true);
  view_.bits = bits_.data();
}

}  // namespace sl
