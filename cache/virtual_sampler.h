// The out-of-core sampler: every sample is read through the page table and the brick cache (DESIGN.md
// "Virtual memory"). A sample at level l uses brick (l, ...) when resident, else the finest resident
// ancestor; the wanted brick is reported once per frame in the unified miss buffer when it is not
// resident, and always inside UNKNOWN segments (an occupancy miss: the host decides, paper §8.2). Plain
// data, SL_HOST_DEVICE: the CUDA caster compiles it unchanged.
#pragma once

#include <cstdint>

#if !defined(__CUDA_ARCH__)
#include <atomic>
#include <type_traits>
#endif

#include "cache/brick.h"
#include "cache/brick_cache.h"
#include "cache/miss_buffer.h"
#include "cache/page_table.h"
#include "core/util/config.h"
#include "core/recon/gradient.h"
#include "core/cast/raycast.h"
#include "core/cast/sample_batch.h"

namespace sl {

// Per-frame counters of samples short of their level of detail, striped so that caster threads
// rarely share a cache line (the stripe follows the caller's stack address). Plain data.
struct SampleShortfall {
  static constexpr std::uint32_t kStripes = 16;
  // 64-byte lines: [0] incomplete, [1] coarsened, [2] left out (samples a voxel mask or a clear fine
  // cell passed over: they count among the frame's samples for completeness, not as taken)
  static constexpr std::uint32_t kStride = 8;
  static constexpr std::uint32_t kWords = kStripes * kStride;
  std::uint64_t* counters = nullptr;           // kStripes * kStride words, zeroed before the cast
  LodParams footprint;                         // the frame's level of detail without pressure
  vec3 eye{0.0f};                              // ray origin of a perspective view (t = distance)
  bool pressured = false;                      // the cast's level of detail is coarser than footprint
  // `counters` is one stripe (kStride words) of one CPU thread's screen tile, added to plainly; the
  // tile adds it to the frame's counters once (add_words) instead of an atomic per span.
  bool local = false;

  SL_HOST_DEVICE SL_INLINE void count(const vec3& p, int level, bool complete) const {
    if (!complete) add(0);
    if (pressured && level > 0 && finer_by_footprint(p, level)) add(1);
  }
  // footprint.level_at(|p - eye|) < level without a square root or a logarithm: the footprint's
  // level is below `level` exactly when its ratio is below 2^level.
  SL_HOST_DEVICE bool finer_by_footprint(const vec3& p, int level) const {
    if (footprint.pixel_size > 0.0f) return footprint.level_at(0.0f) < level;
    const vec3 d = p - eye;
    const float r = footprint.pixel_angle * footprint.inv_voxel;
    const float lim = float(1 << level);
    return glm::dot(d, d) * r * r < lim * lim;
  }

  SL_HOST_DEVICE void count_left_out(std::uint64_t n) const {
    if (counters != nullptr && n != 0) add(2, n);
  }
  // Adds a tile's local stripe (see `local`) to these counters.
  SL_HOST_DEVICE void add_words(const std::uint64_t* w) const {
    if (counters == nullptr) return;
    for (int which = 0; which < 3; ++which) {
      if (w[which] != 0) add(which, w[which]);
    }
  }
  // count() of many samples at once: `incomplete` not served at their level, `coarsened` finer by footprint.
  SL_HOST_DEVICE void count_many(std::uint64_t incomplete, std::uint64_t coarsened) const {
    if (counters == nullptr) return;
    if (incomplete != 0) add(0, incomplete);
    if (coarsened != 0) add(1, coarsened);
  }

 private:
  SL_HOST_DEVICE void add(int which, std::uint64_t n = 1) const {
#if !defined(__CUDA_ARCH__)
    if (local) {
      counters[which] += n;
      return;
    }
#endif
    // Threads' stacks lie whole megabytes apart: hash the page number so they land on different lines.
    const std::uint64_t page = std::uint64_t(reinterpret_cast<std::uintptr_t>(&which)) >> 12;
    const std::uint32_t stripe = std::uint32_t((page * 0x9E3779B97F4A7C15ull) >> 60) % kStripes;
    std::uint64_t* w = counters + stripe * kStride + std::uint32_t(which);
#if defined(__CUDA_ARCH__)
    atomicAdd(reinterpret_cast<unsigned long long*>(w), static_cast<unsigned long long>(n));
#else
    std::atomic_ref<std::uint64_t>(*w).fetch_add(n, std::memory_order_relaxed);
#endif
  }
};

template <class T, class L>
struct VirtualSampler {
  const BrickLayout* layout = nullptr;
  PageTableView page_table;
  BrickCacheView cache;
  MissBufferView misses;
  std::uint32_t frame = 0;
  bool has_labels = false;
  // Completeness accounting (DESIGN.md "Virtual memory", cache pressure); null: not counted. Samples
  // not served at their chosen level (a coarser fallback or nothing) and, under pressure, samples
  // coarser than `footprint` (the level of detail without pressure, from the eye) asks for. Only such
  // samples count, so a complete frame without pressure pays one branch per sample.
  SampleShortfall shortfall;

  // Per-ray brick cursor. The caster marches every span on its own copy of the sampler (RayCaster::
  // march copies itself), so these fields belong to one ray on one thread: consecutive samples in the
  // same wanted brick reuse its page entry and slot sampler instead of a page-table lookup (and the
  // integer division of brick_at) per sample. Reusing them gives exactly the per-sample answer: the
  // page table does not change during a frame, and the miss insert and usage touch it skips are
  // idempotent within a frame (the first sample in the brick did them).
  struct Cursor {
    int level = -1;               // level of the wanted brick (-1: none yet)
    ivec3 lo{0}, hi{0};           // its payload voxels [lo, hi) at that level
    vec3 inv_spacing{0.0f};       // the level's 1 / spacing (as BrickLayout::level_inv_spacing)
    BrickId id;                   // the brick serving it (the wanted one or a resident ancestor)
    PageEntry entry;
    SlotSampler<T> voxels;        // valid when entry is resident
    const std::uint64_t* mask = nullptr;  // the slot's voxel mask, when resident and the frame has masks
    std::uint32_t left_out = 0;   // samples sample_unless_clear passed over (count_left_out adds them)
    bool complete = false;        // the serving brick is the wanted one (not a fallback)
    bool labels_ready = false;
    SlotSampler<L> labels;        // built on first use
  };
  mutable Cursor cur;

  // Entry of the brick serving p: the wanted level if resident, else the finest resident ancestor.
  SL_HOST_DEVICE SL_INLINE const Cursor& locate(const vec3& p, const SampleContext& c) const {
    if (c.level != cur.level) {
      cur.level = c.level;
      cur.inv_spacing = layout->level_inv_spacing(c.level);
      cur.hi = ivec3(0);  // force a lookup
      cur.lo = ivec3(1);
    }
    // brick_at's voxel, step for step.
    const vec3 u = p * cur.inv_spacing;
    const ivec3 d = layout->level_dims[c.level];
    ivec3 v = floor_to_int(u);
    v = glm::clamp(v, ivec3(0), d - 1);
    if (v.x >= cur.lo.x && v.x < cur.hi.x && v.y >= cur.lo.y && v.y < cur.hi.y && v.z >= cur.lo.z &&
        v.z < cur.hi.z) {
      return cur;
    }
    BrickId id = layout->brick_of_voxel(c.level, v);
    cur.lo = id.coord() * layout->brick_size;
    cur.hi = cur.lo + layout->brick_size;
    PageEntry e = page_table.lookup(id);
    if (c.occupancy_unknown || e.state() == PageEntry::State::Unmapped) misses.insert(id);
    for (int l = c.level + 1; !e.is_resident() && e.state() == PageEntry::State::Unmapped && l < layout->levels; ++l) {
      id = layout->brick_at(l, p);
      e = page_table.lookup(id);
    }
    cur.id = id;
    cur.entry = e;
    // Served at the chosen level: the wanted brick itself, resident or known Empty/Constant.
    cur.complete = id.level() == c.level && e.state() != PageEntry::State::Unmapped;
    cur.labels_ready = false;
    if (e.is_resident()) {
      cache.touch(e.slot(), frame);
      cur.voxels = cache.template sampler<T>(e.slot(), *layout, id);
      cur.mask = cache.slot_mask(e.slot());
    } else {
      cur.mask = nullptr;
    }
    return cur;
  }

  // locate, counting the sample's shortfall: what every intensity sample goes through, whichever
  // sampler reads the voxels (this one's software trilinear, the CUDA texture atlas).
  SL_HOST_DEVICE SL_INLINE const Cursor& serve(const vec3& p, const SampleContext& c) const {
    const Cursor& k = locate(p, c);
    if (shortfall.counters) shortfall.count(p, c.level, k.complete);
    return k;
  }

  SL_HOST_DEVICE SL_INLINE float sample(const vec3& p, const SampleContext& c) const { return value(serve(p, c), p); }

  // What the samples from p on have in common until the ray leaves a box, t_exit (the caller leaps
  // over them, or samples one by one on kUnknown):
  // - kClear / kOccupied: the fine cell (BrickCacheView::cells) of the resident brick serving p (the
  //   wanted one, or a resident ancestor's cell within the wanted brick) is clear (no sample in it can
  //   contribute) or not;
  // - kUniform: nothing is resident for p (neither the wanted brick nor an ancestor): every sample in
  //   the wanted brick is served by the same page entry, the value `uniform` (a constant brick's, else 0).
  enum CellState { kUnknown, kClear, kOccupied, kUniform };
  SL_HOST_DEVICE SL_INLINE CellState fine_cell(const Ray& ray, const vec3& inv_dir, const vec3& p,
                                              const SampleContext& c, float& t_exit, float& uniform) const {
    const Cursor& k = locate(p, c);
    if (!k.entry.is_resident()) {
      uniform = value(k, p);
      t_exit = box_exit(ray, inv_dir, k.lo, k.hi, layout->level_spacing(c.level));
      return kUniform;
    }
    if (cache.cells == nullptr || k.mask == nullptr) return kUnknown;
    constexpr int n = BrickCacheView::kCellsPerAxis;
    const int e = layout->brick_size / n;
    // The serving brick's cells, in its own level's voxels (an ancestor's are coarser than the
    // wanted level's).
    const int sl = k.id.level();
    const ivec3 lo = k.id.coord() * layout->brick_size;
    // Truncation for floor: a negative coordinate can only come from a point just outside the
    // volume, and it clamps to the first cell either way.
    const vec3 u = p * (sl == c.level ? k.inv_spacing : layout->level_inv_spacing(sl));
    int cx = (int(u.x) - lo.x) / e, cy = (int(u.y) - lo.y) / e, cz = (int(u.z) - lo.z) / e;
    cx = cx < 0 ? 0 : (cx >= n ? n - 1 : cx);
    cy = cy < 0 ? 0 : (cy >= n ? n - 1 : cy);
    cz = cz < 0 ? 0 : (cz >= n ? n - 1 : cz);
    const std::uint32_t bit = std::uint32_t((cz * n + cy) * n + cx);
    const bool occupied = ((cache.cells[std::uint64_t(k.entry.slot()) * BrickCacheView::kCellWords + (bit >> 6)] >>
                            (bit & 63u)) & 1u) != 0u;
    const ivec3 cell_lo = lo + ivec3(cx, cy, cz) * e;
    t_exit = box_exit(ray, inv_dir, cell_lo, cell_lo + e, layout->level_spacing(sl));
    if (!k.complete) {
      // A fallback serves only the wanted brick's samples: the next wanted brick may be resident.
      const float t_brick = box_exit(ray, inv_dir, k.lo, k.hi, layout->level_spacing(c.level));
      t_exit = t_brick < t_exit ? t_brick : t_exit;
    }
    return occupied ? kOccupied : kClear;
  }

  // Whether fine_cell(p) would answer kClear or kOccupied: the brick serving p is resident, with its
  // fine cells and voxel mask.
  SL_HOST_DEVICE SL_INLINE bool resident_cells(const vec3& p, const SampleContext& c) const {
    const Cursor& k = locate(p, c);
    return k.entry.is_resident() && cache.cells != nullptr && k.mask != nullptr;
  }

  // Where the ray leaves the box [lo, hi) of voxels of spacing h: its far planes.
  SL_HOST_DEVICE SL_INLINE static float box_exit(const Ray& ray, const vec3& inv_dir, const ivec3& lo, const ivec3& hi,
                                                const vec3& h) {
    float t_exit = 3.402823466e+38f;
    for (int a = 0; a < 3; ++a) {
      if (inv_dir[a] == 0.0f) continue;
      const int plane = inv_dir[a] > 0.0f ? hi[a] : lo[a];
      const float t = (float(plane) * h[a] - ray.origin[a]) * inv_dir[a];
      t_exit = t < t_exit ? t : t_exit;
    }
    return t_exit;
  }

  // Whether p's voxel at the cursor's level lies in the cursor's wanted brick (locate would reuse it).
  SL_HOST_DEVICE SL_INLINE bool in_cursor(const vec3& p) const {
    const vec3 u = p * cur.inv_spacing;
    const ivec3 d = layout->level_dims[cur.level];
    ivec3 v = floor_to_int(u);
    v = glm::clamp(v, ivec3(0), d - 1);
    return v.x >= cur.lo.x && v.x < cur.hi.x && v.y >= cur.lo.y && v.y < cur.hi.y && v.z >= cur.lo.z &&
           v.z < cur.hi.z;
  }

  // Where the ray leaves the cursor's wanted brick.
  SL_HOST_DEVICE SL_INLINE float cursor_exit(const Ray& ray, const vec3& inv_dir) const {
    return box_exit(ray, inv_dir, cur.lo, cur.hi, layout->level_spacing(cur.level));
  }

#if !defined(__CUDA_ARCH__)
  // The CPU's tile loop (core/frame/cast_tiles.h) counts each screen tile on its own copy of the sampler
  // into the tile's words (count_tile_into), then adds them to the frame's (add_tile_counts).
  static constexpr int kTileCountWords = int(SampleShortfall::kStride);
  void count_tile_into(std::uint64_t* words) {
    if (shortfall.counters == nullptr) return;
    shortfall.counters = words;
    shortfall.local = true;
  }
  void add_tile_counts(const std::uint64_t* words) const { shortfall.add_words(words); }

  // The cursor's slot as the CPU batch's volume (core/cast/sample_batch.h, DvrBatchArgs::slot), where the
  // brick serving the wanted one (itself, or the resident ancestor standing in for it) is resident with
  // its voxel mask and its voxels are u8 or u16: the batch reads the voxels and mask bits sample() and
  // mask_visible() read, at the serving brick's level, with the same arithmetic. False elsewhere.
  bool slot_batch(DvrBatchArgs& b) const {
    if constexpr (!(std::is_same_v<T, std::uint8_t> || std::is_same_v<T, std::uint16_t>)) {
      (void)b;
      return false;
    } else {
      if (!cur.entry.is_resident() || cur.mask == nullptr) return false;
      const SlotSampler<T>& v = cur.voxels;
      b.slot = true;
      b.data = v.data;
      b.elem_size = int(sizeof(T));
      b.dims = ivec3(v.stored);
      b.first = v.first;
      b.inv_spacing = v.inv_spacing;
      b.hi = vec3(v.dims - 1);
      b.bytes = std::int64_t(v.stored) * v.stored * v.stored * std::int64_t(sizeof(T));
      b.bricks = nullptr;
      b.mask_bits = cur.mask;
      return true;
    }
  }
#endif

  // The shortfall serve() would count for samples t_entry + j * dt, j = k, k + 2^s, ... < next, all
  // served by the cursor's entry (a leap passes over them).
  SL_HOST_DEVICE void count_run(const Ray& ray, float t_entry, float dt, int k, int next, int s,
                                const SampleContext& c) const {
    if (!shortfall.counters || next <= k) return;
    const std::uint64_t n = std::uint64_t(((next - k) + (1 << s) - 1) >> s);
    std::uint64_t coarsened = 0;
    if (shortfall.pressured && c.level > 0) {
      for (int j = k; j < next; j += 1 << s) coarsened += shortfall.finer_by_footprint(ray.at(t_entry + float(j) * dt), c.level);
    }
    shortfall.count_many(cur.complete ? 0 : n, coarsened);
  }

  // Adds the samples this ray's cursor passed over, and `leapt` more, to the frame's left-out count.
  SL_HOST_DEVICE void count_left_out(std::uint64_t leapt) const {
    shortfall.count_left_out(leapt + cur.left_out);
    cur.left_out = 0;
  }

  // sample(), unless the serving slot's voxel mask says the sample cannot contribute: then false, and
  // nothing is fetched. The miss, usage and shortfall accounting are those of sample() either way.
  SL_HOST_DEVICE SL_INLINE bool sample_unless_clear(const vec3& p, const SampleContext& c, float& v) const {
    const Cursor& k = serve(p, c);
    if (k.mask != nullptr && !k.voxels.mask_visible(p, k.mask)) {
      ++cur.left_out;
      return false;
    }
    v = value(k, p);
    return true;
  }

  SL_HOST_DEVICE SL_INLINE float value(const Cursor& k, const vec3& p) const {
    if (k.entry.is_resident()) return k.voxels.sample(p);
    if (k.entry.state() == PageEntry::State::Constant) return k.entry.constant_value(cache.voxel_type);
    return 0.0f;  // empty, or nothing resident yet: rendered as missing
  }

  SL_HOST_DEVICE SL_INLINE std::uint32_t label_at(const vec3& p, const SampleContext& c) const {
    if (!has_labels) return 0u;
    const Cursor& k = locate(p, c);
    if (!k.entry.is_resident()) return 0u;
    if (!k.labels_ready) {
      cur.labels = cache.template label_sampler<L>(k.entry.slot(), *layout, k.id);
      cur.labels_ready = true;
    }
    return k.labels.label_at(p);
  }

  // Central differences one voxel of the sampled level apart (not counted as samples).
  SL_HOST_DEVICE vec3 gradient(const vec3& p, const vec3& spacing, const SampleContext& c) const {
    return central_difference_gradient(p, spacing * float(1 << c.level),
                                       [this, &c](const vec3& q) { return value(locate(q, c), q); });
  }
};

}  // namespace sl
