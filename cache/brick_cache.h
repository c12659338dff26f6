// Brick cache (DESIGN.md "Virtual memory"): a fixed pool of slots, each one (B + 2)³ brick of the voxel
// type (plus its labels when the volume has them, and for u8/u16 a voxel mask of its cells), held in two contiguous slabs on the CPU (a 3D atlas
// on CUDA). Sized once from a memory budget (--cache-mb). Replacement is LRU over per-slot usage stamps
// — the frame number in which the ray caster last sampled the slot (paper §8.3: usage reporting drives
// both the cache and the occupancy tree's retirement).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <utility>
#include <vector>

#if !defined(__CUDA_ARCH__)
#include <atomic>
#endif

#include "cache/brick.h"
#include "core/util/config.h"
#include "core/util/math.h"
#include "core/recon/sampling.h"
#include "core/scene/volume.h"

namespace sl {

// Trilinear sampling inside one resident brick, for the caster's inner loop (it stays in a brick
// without page-table lookups until the ray leaves it, DESIGN.md "Ray casting"). Uses DenseGrid's arithmetic
// verbatim on level coordinates, so at level 0 it returns bit-identical values to
// DenseGrid<T>::sample for any point in the brick's payload region: the apron holds the neighbours
// (or the clamped edge voxel, where DenseGrid reuses x0 as x1 and the difference is exactly 0).
template <class T>
struct SlotSampler {
  const T* data = nullptr;  // (B + 2)³ stored voxels
  ivec3 first{0};           // level voxel held by stored voxel 0 (brick origin - 1)
  ivec3 dims{0};            // the level's dims (clamping, as DenseGrid clamps to the edge voxels)
  vec3 inv_spacing{1.0f};   // the level's 1 / spacing
  std::int32_t stored = 0;  // B + 2

  SL_HOST_DEVICE float sample(const vec3& p) const {
    vec3 u = p * inv_spacing - 0.5f;
    u = glm::clamp(u, vec3(0.0f), vec3(dims - 1));
    const int x0 = int(u.x), y0 = int(u.y), z0 = int(u.z);
    const float fx = u.x - float(x0), fy = u.y - float(y0), fz = u.z - float(z0);
    // Local stored indices; the clamp only matters for points outside the payload (never read
    // outside the slot), inside it is a no-op.
    const int lx = clampi(x0 - first.x), ly = clampi(y0 - first.y), lz = clampi(z0 - first.z);
    const std::int64_t sx = stored, sxy = std::int64_t(stored) * stored;
    const T* b = data + lx;
    // x1 = lx + 1 always exists in the slot (apron); where DenseGrid clamps x1 to x0 at the volume's
    // edge the apron repeats the edge voxel, so the blend is the same.
    return trilerp(b + (lz * sxy + ly * sx), b + (lz * sxy + (ly + 1) * sx), b + ((lz + 1) * sxy + ly * sx),
                   b + ((lz + 1) * sxy + (ly + 1) * sx), 1, fx, fy, fz);
  }
  // Label of the voxel containing p (nearest neighbour), as DenseGrid::label_at.
  SL_HOST_DEVICE std::uint32_t label_at(const vec3& p) const {
    const vec3 u = p * inv_spacing;
    ivec3 v = floor_to_int(u);
    v = glm::clamp(v, ivec3(0), dims - 1) - first;
    v = glm::clamp(v, ivec3(0), ivec3(stored - 1));
    return std::uint32_t(data[(std::int64_t(v.z) * stored + v.y) * stored + v.x]);
  }

  // The bit of the slot's voxel mask (BrickCacheView::masks) for the trilinear cell sample(p) blends:
  // the same local anchor, so a clear bit means sample(p) cannot contribute (DESIGN.md "Ray casting").
  // The mask holds a bit per stored voxel, packed x fastest.
  SL_HOST_DEVICE bool mask_visible(const vec3& p, const std::uint64_t* mask) const {
    vec3 u = p * inv_spacing - 0.5f;
    u = glm::clamp(u, vec3(0.0f), vec3(dims - 1));
    const int lx = clampi(int(u.x) - first.x), ly = clampi(int(u.y) - first.y), lz = clampi(int(u.z) - first.z);
    const std::uint64_t bit = std::uint64_t((std::int64_t(lz) * stored + ly) * stored + lx);
    return ((mask[bit >> 6] >> (bit & 63u)) & 1u) != 0u;
  }

 private:
  SL_HOST_DEVICE int clampi(int i) const { return i < 0 ? 0 : (i > stored - 2 ? stored - 2 : i); }
};

// The caster's view of the cache: plain, copyable to a device.
struct BrickCacheView {
  std::byte* voxels = nullptr;        // slot s at voxels + s * voxel_stride
  std::byte* labels = nullptr;        // nullptr when the volume has no labels
  std::uint32_t* usage = nullptr;     // per slot: frame of last use
  std::uint64_t voxel_stride = 0;     // bytes per slot
  std::uint64_t label_stride = 0;
  std::uint32_t slot_count = 0;
  std::int32_t stored = 0;            // B + 2
  VoxelType voxel_type = VoxelType::U8;
  VoxelType label_type = VoxelType::U32;
  std::uint8_t has_labels = 0;
  std::uint8_t pad_[5] = {};
  // Per slot, the voxel mask of its stored voxels under the frame's culling inputs (a bit per trilinear
  // cell, packed x fastest; core/occupancy/fine_occupancy.h): the caster leaves out the samples whose
  // bit is clear. Null: no masks (other modes or filters, other voxel types, devices with their own
  // memory).
  const std::uint64_t* masks = nullptr;
  std::uint32_t mask_words = 0;      // per slot
  std::uint32_t pad_mask_ = 0;
  // Per slot, kCellsPerAxis³ fine cells of (B / kCellsPerAxis)³ payload voxels in kCellWords words,
  // bit (z * n + y) * n + x set when a sample within half a voxel of the cell can contribute: the OR of
  // the mask bits of the trilinear cells such a sample may blend. The caster leaps over a clear cell
  // without visiting its samples. With masks.
  static constexpr int kCellsPerAxis = 8;
  static constexpr int kCellWords = kCellsPerAxis * kCellsPerAxis * kCellsPerAxis / 64;
  const std::uint64_t* cells = nullptr;

  // Reports that slot s was used in `frame`. Many caster threads do this at once with the same
  // frame value, so a relaxed store suffices; the load first avoids dirtying a shared cache line.
  SL_HOST_DEVICE void touch(std::uint32_t slot, std::uint32_t frame) const {
#if defined(__CUDA_ARCH__)
    if (usage[slot] != frame) usage[slot] = frame;
#else
    std::atomic_ref<std::uint32_t> u(usage[slot]);
    if (u.load(std::memory_order_relaxed) != frame) u.store(frame, std::memory_order_relaxed);
#endif
  }

  template <class T>
  SL_HOST_DEVICE const T* slot_voxels(std::uint32_t slot) const {
    return reinterpret_cast<const T*>(voxels + std::uint64_t(slot) * voxel_stride);
  }
  SL_HOST_DEVICE const std::uint64_t* slot_mask(std::uint32_t slot) const {
    return masks ? masks + std::uint64_t(slot) * mask_words : nullptr;
  }
  template <class L>
  SL_HOST_DEVICE const L* slot_labels(std::uint32_t slot) const {
    return reinterpret_cast<const L*>(labels + std::uint64_t(slot) * label_stride);
  }

  // Sampler over slot `slot`, which holds brick `id` of `layout`.
  template <class T>
  SL_HOST_DEVICE SlotSampler<T> sampler(std::uint32_t slot, const BrickLayout& layout, BrickId id) const {
    return make_sampler(slot_voxels<T>(slot), layout, id);
  }
  template <class L>
  SL_HOST_DEVICE SlotSampler<L> label_sampler(std::uint32_t slot, const BrickLayout& layout, BrickId id) const {
    return make_sampler(slot_labels<L>(slot), layout, id);
  }

  template <class T>
  SL_HOST_DEVICE static SlotSampler<T> make_sampler(const T* data, const BrickLayout& layout, BrickId id) {
    SlotSampler<T> s;
    s.data = data;
    s.first = layout.brick_origin(id) - kBrickApron;
    s.dims = layout.dims(id.level());
    s.inv_spacing = layout.level_inv_spacing(id.level());
    s.stored = layout.stored_size();
    return s;
  }
};
static_assert(sizeof(BrickCacheView) == 80, "BrickCacheView is plain data");

class BrickCache {
 public:
  // Slots are as many whole bricks as fit in budget_mb MiB (voxels + labels, each slot's arrays
  // rounded up to 64 bytes). Throws InputError("--cache-mb", ...) when that is fewer than one brick
  // per level — the caster needs at least the coarsest brick of every level it falls back to.
  // label_type is std::nullopt for a volume without labels. Memory is committed lazily by the OS as
  // slots are first written, so a large budget costs nothing until it fills.
  BrickCache(const BrickLayout& layout, VoxelType voxel_type, std::optional<VoxelType> label_type,
             std::size_t budget_mb);

  struct Allocation {
    std::uint32_t slot = 0;
    BrickId evicted;  // the brick that held the slot (invalid when the slot was free): clear its entry
  };
  // A slot for brick `id`: a free one if any, else the least recently used slot whose last use is
  // before `frame` (ties: lowest slot). Slots used in `frame` or later are never evicted: returns
  // std::nullopt when every slot is. The slot is stamped `frame`, so bricks uploaded in one batch
  // do not evict each other.
  std::optional<Allocation> allocate(BrickId id, std::uint32_t frame);
  // Frees a slot (e.g. its brick turned out to be Empty/Constant, or failed).
  void release(std::uint32_t slot);

  std::uint32_t slot_count() const { return slot_count_; }
  std::uint32_t resident_count() const { return slot_count_ - std::uint32_t(free_.size()); }
  std::size_t slot_bytes() const { return voxel_stride_ + label_stride_ + mask_words_ * sizeof(std::uint64_t); }
  double resident_mb() const { return double(resident_count()) * double(slot_bytes()) / double(1 << 20); }
  std::uint64_t evictions() const { return evictions_; }
  BrickId brick_in(std::uint32_t slot) const { return owner_[slot]; }
  std::uint32_t last_used(std::uint32_t slot) const;
  bool has_labels() const { return label_stride_ != 0; }

  std::span<std::byte> slot_voxels(std::uint32_t slot);
  std::span<std::byte> slot_labels(std::uint32_t slot);  // empty without labels
  // The slot's voxel mask words (empty where masks_supported() is false) and the culling key it was
  // built for (kNoMask: none, e.g. the slot was just refilled).
  static constexpr std::uint64_t kNoMask = 0;
  bool masks_supported() const { return mask_words_ != 0; }
  std::span<std::uint64_t> slot_mask(std::uint32_t slot);
  std::span<const std::uint64_t> slot_mask(std::uint32_t slot) const;
  // The slot's fine cells, derived from its mask (BrickCacheView::cells).
  std::span<std::uint64_t> slot_cells(std::uint32_t slot) {
    return {cells_.data() + std::size_t(slot) * BrickCacheView::kCellWords, BrickCacheView::kCellWords};
  }
  std::uint64_t mask_key(std::uint32_t slot) const { return mask_key_[slot]; }
  void set_mask_key(std::uint32_t slot, std::uint64_t key) { mask_key_[slot] = key; }

  BrickCacheView view();

 private:
  BrickLayout layout_;
  VoxelType voxel_type_;
  VoxelType label_type_;
  std::size_t voxel_stride_ = 0, label_stride_ = 0;
  std::uint32_t slot_count_ = 0;
  std::unique_ptr<std::byte[]> voxels_, labels_;
  std::size_t mask_words_ = 0;  // per slot (0: no masks)
  std::unique_ptr<std::uint64_t[]> masks_;
  std::vector<std::uint64_t> mask_key_;
  std::vector<std::uint64_t> cells_;
  std::vector<std::uint32_t> usage_;  // written by casters through the view (atomic_ref)
  std::vector<BrickId> owner_;
  std::vector<std::uint32_t> free_;   // free slots, taken from the back (lowest first)
  // Eviction candidates (usage stamp, slot) sorted oldest last, built when needed and re-validated
  // on use, so a batch of k allocations costs one O(n log n) sort rather than k scans.
  std::vector<std::pair<std::uint32_t, std::uint32_t>> candidates_;
  std::uint32_t candidates_frame_ = 0;
  std::uint64_t evictions_ = 0;
};

}  // namespace sl
