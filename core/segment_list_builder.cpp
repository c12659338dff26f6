#include "core/segment_list_builder.h"

#include "core/list_arena.h"
#include "core/parallel.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <type_traits>
#include <vector>

#if defined(__SSE2__) && !defined(SL_NO_SSE)
#include <emmintrin.h>
#define SL_SSE_SLAB 1
#else
#define SL_SSE_SLAB 0
#endif
#if SL_SSE_SLAB && defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define SL_AVX2_SLAB 1
#else
#define SL_AVX2_SLAB 0
#endif

namespace sl {

namespace {

// The 4-wide slab test (detail::slab4), inlined into the tile loop. Scalar: intersect() written out
// per lane. With slab_reciprocal's +inf an axis the ray is parallel to yields u, v in {-inf, +inf,
// NaN}: -inf/+inf leave [t0, t1] alone, a +inf near (origin below the slab) or a -inf far (above it)
// empties it, and NaN (origin on the slab's plane) fails every comparison and changes nothing — the
// origin is within the inclusive slab there, as intersect() decides. Fast: the same IEEE operations
// four lanes at a time; minps/maxps return their second operand unless their comparison holds,
// which is exactly the scalar `a > b ? a : b` (NaN lanes included).
// Both forms below: kShared, the four rays share their origin and lo, hi are the box's corners minus
// it (made once per box); else lo, hi are the corners and each lane subtracts its own origin o.
template <ListBuildPath kPath, bool kShared>
SL_INLINE unsigned slab_impl(const float* const o[3], const float* const inv[3], std::size_t i, const float* lo,
                             const float* hi, float* t0, float* t1) {
#if SL_SSE_SLAB
  if constexpr (kPath == ListBuildPath::Fast) {
    __m128 near = _mm_set1_ps(-3.402823466e+38f);
    __m128 far = _mm_set1_ps(3.402823466e+38f);
    for (int a = 0; a < 3; ++a) {
      const __m128 ia = _mm_loadu_ps(inv[a] + i);
      __m128 dl = _mm_set1_ps(lo[a]), dh = _mm_set1_ps(hi[a]);
      if constexpr (!kShared) {
        const __m128 oa = _mm_loadu_ps(o[a] + i);
        dl = _mm_sub_ps(dl, oa);
        dh = _mm_sub_ps(dh, oa);
      }
      const __m128 u = _mm_mul_ps(dl, ia);
      const __m128 v = _mm_mul_ps(dh, ia);
      near = _mm_max_ps(_mm_min_ps(v, u), near);  // min: u > v ? v : u; max: lo > near ? lo : near
      far = _mm_min_ps(_mm_max_ps(u, v), far);    // max: u > v ? u : v; min: hi < far ? hi : far
    }
    _mm_storeu_ps(t0, near);
    _mm_storeu_ps(t1, far);
    return unsigned(_mm_movemask_ps(_mm_and_ps(_mm_cmplt_ps(near, far), _mm_cmpgt_ps(far, _mm_setzero_ps()))));
  }
#endif
  unsigned hit = 0;
  for (int k = 0; k < 4; ++k) {
    float near = -3.402823466e+38f;
    float far = 3.402823466e+38f;
    for (int a = 0; a < 3; ++a) {
      const float dl = kShared ? lo[a] : lo[a] - o[a][i + k], dh = kShared ? hi[a] : hi[a] - o[a][i + k];
      float u = dl * inv[a][i + k];
      float v = dh * inv[a][i + k];
      if (u > v) std::swap(u, v);
      near = u > near ? u : near;
      far = v < far ? v : far;
    }
    t0[k] = near;
    t1[k] = far;
    if (near < far && far > 0.0f) hit |= 1u << k;
  }
  return hit;
}

template <ListBuildPath kPath>
SL_INLINE unsigned slab_lanes(const float* const o[3], const float* const inv[3], std::size_t i, const Box3& b,
                              float* t0, float* t1) {
  return slab_impl<kPath, false>(o, inv, i, &b.lo.x, &b.hi.x, t0, t1);
}

// slab_lanes for rays sharing their origin (perspective): lo_o, hi_o are the box's corners minus that
// origin, made once per box; per lane the same IEEE operations as slab_lanes on the same values.
template <ListBuildPath kPath>
SL_INLINE unsigned slab_lanes_shared(const float* const inv[3], std::size_t i, const float lo_o[3],
                                     const float hi_o[3], float* t0, float* t1) {
  return slab_impl<kPath, true>(nullptr, inv, i, lo_o, hi_o, t0, t1);
}

// Bit k set when x[k] > 0 (k < 4).
template <ListBuildPath kPath>
SL_INLINE unsigned positive_lanes(const float* x) {
#if SL_SSE_SLAB
  if constexpr (kPath == ListBuildPath::Fast) {
    return unsigned(_mm_movemask_ps(_mm_cmpgt_ps(_mm_loadu_ps(x), _mm_setzero_ps())));
  }
#endif
  unsigned m = 0;
  for (int k = 0; k < 4; ++k) m |= x[k] > 0.0f ? 1u << k : 0u;
  return m;
}

// dst[k] = t[k] where bit k of `lanes` is set, else 0 (k < 4).
template <ListBuildPath kPath>
SL_INLINE void store_lanes(float* dst, const float* t, unsigned lanes) {
#if SL_SSE_SLAB
  if constexpr (kPath == ListBuildPath::Fast) {
    const __m128i bits = _mm_setr_epi32(1, 2, 4, 8);
    const __m128i mask = _mm_cmpeq_epi32(_mm_and_si128(_mm_set1_epi32(int(lanes)), bits), bits);
    _mm_storeu_ps(dst, _mm_and_ps(_mm_loadu_ps(t), _mm_castsi128_ps(mask)));
    return;
  }
#endif
  for (int k = 0; k < 4; ++k) dst[k] = (lanes >> k) & 1u ? t[k] : 0.0f;
}

}  // namespace

namespace detail {

template <ListBuildPath kPath>
unsigned slab4(const float* const o[3], const float* const inv[3], std::size_t i, const Box3& b, float* t0,
               float* t1) {
  return slab_lanes<kPath>(o, inv, i, b, t0, t1);
}
template unsigned slab4<ListBuildPath::Fast>(const float* const[3], const float* const[3], std::size_t, const Box3&,
                                             float*, float*);
template unsigned slab4<ListBuildPath::Scalar>(const float* const[3], const float* const[3], std::size_t,
                                               const Box3&, float*, float*);

template <ListBuildPath kPath>
unsigned slab4_shared(const float* const inv[3], std::size_t i, const vec3& origin, const Box3& b, float* t0,
                      float* t1) {
  float lo_o[3], hi_o[3];
  for (int a = 0; a < 3; ++a) {
    lo_o[a] = b.lo[a] - origin[a];
    hi_o[a] = b.hi[a] - origin[a];
  }
  return slab_lanes_shared<kPath>(inv, i, lo_o, hi_o, t0, t1);
}
template unsigned slab4_shared<ListBuildPath::Fast>(const float* const[3], std::size_t, const vec3&, const Box3&,
                                                    float*, float*);
template unsigned slab4_shared<ListBuildPath::Scalar>(const float* const[3], std::size_t, const vec3&, const Box3&,
                                                      float*, float*);

}  // namespace detail

using detail::count_list;
using detail::EventArena;
using detail::ListBlock;
using detail::sum_stats;

SegmentListStats segment_list_stats(const SegmentListBuffer& lists) {
  const std::size_t n = lists.counts.size();
  return parallel_reduce(
      std::size_t(0), n, std::size_t(1), SegmentListStats{},
      [&](std::size_t lo, std::size_t hi, SegmentListStats s) {
        for (std::size_t i = lo; i != hi; ++i) count_list(s, lists.list(i), lists.counts[i]);
        return s;
      },
      sum_stats);
}

namespace {

constexpr int T = kTileSize;
constexpr int kTilePixels = T * T;
static_assert(kTilePixels % 64 == 0 && T % 4 == 0, "a tile's hits fill 64-bit words; no group of four straddles two");

// Runs fn(tile_rect, entries, stats) for every screen tile, in parallel over rows of tiles: each row
// first bins, in the given order, the items whose rectangle overlaps it (a tile may have none).
// `rect_of(i)` is item i's rectangle. Returns the stats fn added up, with box_tile_pairs.
template <class RectOf, class Fn>
SegmentListStats for_each_tile(const RayGenerator& gen, std::size_t items, RectOf&& rect_of, Fn&& fn) {
  const int tiles_x = (gen.width + T - 1) / T;
  const int tiles_y = (gen.height + T - 1) / T;
  // The items of each row of tiles, in item order, made in one pass over the items (count, prefix
  // sum, fill) instead of one pass per row.
  std::vector<std::uint32_t> row_start(std::size_t(tiles_y) + 1, 0u), row_items;
  for (std::size_t i = 0; i < items; ++i) {
    const ScreenRect& r = rect_of(i);
    if (r.empty()) continue;
    for (int ty = r.y0 / T; ty <= r.y1 / T; ++ty) ++row_start[std::size_t(ty) + 1];
  }
  for (int ty = 0; ty < tiles_y; ++ty) row_start[std::size_t(ty) + 1] += row_start[std::size_t(ty)];
  row_items.resize(row_start.back());
  std::vector<std::uint32_t> at(row_start.begin(), row_start.end() - 1);
  for (std::size_t i = 0; i < items; ++i) {
    const ScreenRect& r = rect_of(i);
    if (r.empty()) continue;
    for (int ty = r.y0 / T; ty <= r.y1 / T; ++ty) row_items[at[std::size_t(ty)]++] = std::uint32_t(i);
  }
  return parallel_reduce(
      0, tiles_y, 1, SegmentListStats{},
      [&](int row0, int row1, SegmentListStats st) {
        thread_local std::vector<std::vector<std::uint32_t>> bins;  // kept: no allocation per frame
        if (bins.size() < std::size_t(tiles_x)) bins.resize(std::size_t(tiles_x));
        for (int ty = row0; ty != row1; ++ty) {
          for (int tx = 0; tx < tiles_x; ++tx) bins[tx].clear();
          const int y0 = ty * T, y1 = std::min(y0 + T, gen.height) - 1;
          for (std::uint32_t j = row_start[std::size_t(ty)]; j != row_start[std::size_t(ty) + 1]; ++j) {
            const std::uint32_t i = row_items[j];
            const ScreenRect& r = rect_of(i);
            for (int tx = r.x0 / T; tx <= r.x1 / T; ++tx) bins[tx].push_back(i);
          }
          for (int tx = 0; tx < tiles_x; ++tx) {
            const ScreenRect tile{tx * T, y0, std::min(tx * T + T, gen.width) - 1, y1};
            st.box_tile_pairs += bins[tx].size();
            fn(tile, bins[tx], st);
          }
        }
        return st;
      },
      sum_stats);
}

std::vector<ScreenRect> box_rects(std::span<const OccupancyBox> boxes, const RayGenerator& gen) {
  std::vector<ScreenRect> rects(boxes.size());
  parallel_for(std::size_t(0), boxes.size(), [&](std::size_t i) { rects[i] = conservative_screen_rect(boxes[i].box, gen); });
  return rects;
}

// add_event's common case, written out: an event later than every depth the list has seen, that
// changes the class, with room for it and no short-gap rule (eps = 0) meets none of Alg. 5's rules
// and is appended as it is. Anything else goes through add_event. Exactly add_event's result: the
// list's tail lies at or before t_seen, so no same-depth rule can apply; an overflowed count word
// (top bit) fails the room test.
SL_INLINE void append_event(RayEvent* list, std::uint32_t& count, float& t_seen, std::uint32_t cap, float t,
                            EventType type, OccupancyClass cls, float eps) {
  const std::uint32_t n = count;
  if (n < cap && t > t_seen && !(eps > 0.0f) && (n == 0u || list[n - 1].cls != std::uint8_t(cls))) {
    list[n] = detail::make_event(t, type, cls);
    count = n + 1u;
    t_seen = t;
    return;
  }
  add_event(list, count, t_seen, cap, t, type, cls, eps);
}

// A leaf's ENTRY at t_in and EXIT at t_out (Alg. 4) as two add_event calls would add them; both at
// once in the common case (append_event's, for the pair: the exit after the entry and back to a class
// other than the leaf's).
SL_INLINE void append_leaf(RayEvent* list, std::uint32_t& count, float& t_seen, std::uint32_t cap, float t_in,
                           float t_out, OccupancyClass cls, OccupancyClass parent_cls, float eps) {
  const std::uint32_t n = count;
  if (n < cap && cap - n >= 2u && t_in > t_seen && t_out > t_in && !(eps > 0.0f) && cls != parent_cls &&
      (n == 0u || list[n - 1].cls != std::uint8_t(cls))) {
    list[n] = detail::make_event(t_in, EventType::Entry, cls);
    list[n + 1] = detail::make_event(t_out, EventType::Exit, parent_cls);
    count = n + 2u;
    t_seen = t_out;
    return;
  }
  // The next leaf of a run of same-class leaves sharing faces: its ENTRY meets the previous leaf's EXIT
  // at the same depth and, returning to the class before it, deletes it (Alg. 5, rule 3); its EXIT
  // then takes the freed slot. Exactly add_event's two results: the list is sorted, so the event
  // before the deleted one lies at or before the entry and the exit, later, meets no same-depth rule.
  const float t_at = t_in > t_seen ? t_in : t_seen;  // the entry's depth after the monotonicity guard
  if (n < cap && n >= 2u && !(eps > 0.0f) && cls != parent_cls && t_out > t_at &&
      list[n - 1].type == std::uint8_t(EventType::Exit) && list[n - 1].t == t_at &&
      list[n - 2].cls == std::uint8_t(cls)) {
    list[n - 1] = detail::make_event(t_out, EventType::Exit, parent_cls);
    t_seen = t_out;
    return;
  }
  append_event(list, count, t_seen, cap, t_in, EventType::Entry, cls, eps);
  append_event(list, count, t_seen, cap, t_out, EventType::Exit, parent_cls, eps);
}

// dst[0, n) = src[0, n), n >= 1: a list is a few events, too short for a call to memcpy to pay.
// `room`: the events dst can take (n at least). With room for eight, eight are copied whatever n (the
// ones past n are overwritten by the next list, or lie past the events): one fixed-size copy, no
// loop whose length is as good as random.
SL_INLINE void copy_events(RayEvent* dst, const RayEvent* src, std::uint32_t n, std::size_t room) {
  static_assert(sizeof(RayEvent) == 8 && std::is_trivially_copyable_v<RayEvent>);
  if (n <= 8u && room >= 8u) {
    std::memcpy(dst, src, 8 * sizeof(RayEvent));
    return;
  }
  std::uint32_t i = 0;
#if SL_SSE_SLAB
  for (; i + 2u <= n; i += 2u) {
    _mm_storeu_si128(reinterpret_cast<__m128i*>(dst + i), _mm_loadu_si128(reinterpret_cast<const __m128i*>(src + i)));
  }
#endif
  for (; i < n; ++i) std::memcpy(dst + i, src + i, sizeof(RayEvent));
}

// A tile's working set, one per thread and kept between frames. Pixel k = ly * T + lx of the tile.
struct TileScratch {
  alignas(16) float origin[3][kTilePixels];
  alignas(16) float inv_dir[3][kTilePixels];
  alignas(16) float t0[kTilePixels], t1[kTilePixels];  // an entry's slab intervals
  std::vector<float> exits;  // [level][pixel]: exit t of the open box at that level, 0 where it missed
  std::uint32_t capacity = 32;
  std::vector<RayEvent> events;  // [pixel][capacity]
  std::uint32_t count[kTilePixels];
  float t_seen[kTilePixels];
};

// An entry of the visibility order with all the tile loop reads of it, gathered once per frame in
// that order. A tile visits its entries in order, so it reads this array forward, where the boxes and
// their rectangles, indexed by box, were read at random (a cache miss an entry once the frame's
// working set outgrew the caches).
struct EntryRec {
  Box3 box;
  ScreenRect rect;
  std::uint32_t level;  // nesting level (nesting_levels)
  OccupancyClass cls, parent_cls;
  bool front;  // a FRONT entry, else a BACK one
  bool leaf;   // a FRONT entry whose box's BACK entry comes next (a leaf's, Alg. 3)
};
static_assert(sizeof(EntryRec) == 48, "EntryRec layout");

// The frame's entry records, in `rec` (kept by the caller between frames: no allocation, no zero
// fill per frame once it has seen its largest order). One parallel pass makes them, a FRONT entry's
// with its box's screen rectangle; a BACK entry then takes its FRONT entry's rectangle. Checks what
// the tile builder relies on: every BACK entry closes the box opened last. `depth`: the deepest
// nesting level + 1.
void entry_records(const OccupancyGeometry& geometry, std::span<const VisibilityEntry> order, const RayGenerator& gen,
                   std::vector<EntryRec>& rec, std::uint32_t& depth) {
  // Kept per calling thread; the parallel loop's workers see them through these references (a
  // thread_local named in a lambda would be the worker's own).
  thread_local std::vector<std::uint32_t> level_kept, opener_kept, open_kept;
  std::vector<std::uint32_t>& level = level_kept;
  std::vector<std::uint32_t>& opener = opener_kept;  // a BACK entry's FRONT entry
  std::vector<std::uint32_t>& open = open_kept;
  level.resize(order.size());
  opener.resize(order.size());
  open.clear();
  depth = 0;
  for (std::size_t i = 0; i < order.size(); ++i) {
    if (order[i].face == Face::Front) {
      level[i] = std::uint32_t(open.size());
      open.push_back(std::uint32_t(i));
      depth = std::max(depth, std::uint32_t(open.size()));
    } else {
      SL_CHECK(!open.empty() && order[open.back()].box == order[i].box);
      opener[i] = open.back();
      open.pop_back();
      level[i] = std::uint32_t(open.size());
    }
  }
  SL_CHECK(open.empty());
  rec.resize(order.size());
  parallel_for(std::size_t(0), order.size(), [&](std::size_t lo, std::size_t hi) {
    for (std::size_t e = lo; e != hi; ++e) {
      const VisibilityEntry& v = order[e];
      const OccupancyBox& b = geometry.boxes[v.box];
      const bool front = v.face == Face::Front;
      const bool leaf = front && e + 1 < order.size() && order[e + 1].box == v.box;
      rec[e] = EntryRec{b.box, front ? conservative_screen_rect(b.box, gen) : ScreenRect{}, level[e], b.cls,
                        b.parent_cls, front, leaf};
    }
  });
  for (std::size_t e = 0; e < order.size(); ++e) {
    if (!rec[e].front) rec[e].rect = rec[opener[e]].rect;
  }
}

struct TileJob {
  std::span<const EntryRec> entries;
  const RayGenerator& gen;
  std::uint32_t depth;
  float eps;
  EventArena& arena;
  SegmentListBuffer& out;
};

namespace lanes4 {  // SSE2, or the scalar twin

constexpr int kLanes = 4;
template <ListBuildPath kPath>
SL_INLINE unsigned lanes_slab(const float* const o[3], const float* const inv[3], std::size_t i, const Box3& b,
                              float* t0, float* t1) {
  return slab_lanes<kPath>(o, inv, i, b, t0, t1);
}
template <ListBuildPath kPath>
SL_INLINE unsigned lanes_slab_shared(const float* const inv[3], std::size_t i, const float lo_o[3],
                                     const float hi_o[3], float* t0, float* t1) {
  return slab_lanes_shared<kPath>(inv, i, lo_o, hi_o, t0, t1);
}
template <ListBuildPath kPath>
SL_INLINE void lanes_store(float* dst, const float* t, unsigned lanes) {
  store_lanes<kPath>(dst, t, lanes);
}
template <ListBuildPath kPath>
SL_INLINE unsigned lanes_positive(const float* x) {
  return positive_lanes<kPath>(x);
}

#include "core/list_tile_raster.inc"

}  // namespace lanes4

#if SL_AVX2_SLAB
#if defined(__clang__)
#pragma clang attribute push(__attribute__((target("avx2"))), apply_to = function)
#else
#pragma GCC push_options
#pragma GCC target("avx2")
#endif
namespace lanes8 {  // AVX2: everything defined here is compiled for it, and runs only where the host has it

constexpr int kLanes = 8;
// slab_impl's SSE2 code eight lanes wide: the same IEEE operations per lane (vminps, vmaxps return
// their second operand as minps, maxps do; the ordered, quiet compares are cmpltps, cmpgtps).
template <bool kShared>
SL_INLINE unsigned slab8(const float* const o[3], const float* const inv[3], std::size_t i, const float* lo,
                         const float* hi, float* t0, float* t1) {
  __m256 near = _mm256_set1_ps(-3.402823466e+38f);
  __m256 far = _mm256_set1_ps(3.402823466e+38f);
  for (int a = 0; a < 3; ++a) {
    const __m256 ia = _mm256_loadu_ps(inv[a] + i);
    __m256 dl = _mm256_set1_ps(lo[a]), dh = _mm256_set1_ps(hi[a]);
    if constexpr (!kShared) {
      const __m256 oa = _mm256_loadu_ps(o[a] + i);
      dl = _mm256_sub_ps(dl, oa);
      dh = _mm256_sub_ps(dh, oa);
    }
    const __m256 u = _mm256_mul_ps(dl, ia);
    const __m256 v = _mm256_mul_ps(dh, ia);
    near = _mm256_max_ps(_mm256_min_ps(v, u), near);
    far = _mm256_min_ps(_mm256_max_ps(u, v), far);
  }
  _mm256_storeu_ps(t0, near);
  _mm256_storeu_ps(t1, far);
  return unsigned(_mm256_movemask_ps(
      _mm256_and_ps(_mm256_cmp_ps(near, far, _CMP_LT_OQ), _mm256_cmp_ps(far, _mm256_setzero_ps(), _CMP_GT_OQ))));
}
template <ListBuildPath kPath>
SL_INLINE unsigned lanes_slab(const float* const o[3], const float* const inv[3], std::size_t i, const Box3& b,
                              float* t0, float* t1) {
  static_assert(kPath == ListBuildPath::Fast);
  return slab8<false>(o, inv, i, &b.lo.x, &b.hi.x, t0, t1);
}
template <ListBuildPath kPath>
SL_INLINE unsigned lanes_slab_shared(const float* const inv[3], std::size_t i, const float lo_o[3],
                                     const float hi_o[3], float* t0, float* t1) {
  static_assert(kPath == ListBuildPath::Fast);
  return slab8<true>(nullptr, inv, i, lo_o, hi_o, t0, t1);
}
template <ListBuildPath kPath>
SL_INLINE void lanes_store(float* dst, const float* t, unsigned lanes) {
  const __m256i bits = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
  const __m256i mask = _mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32(int(lanes)), bits), bits);
  _mm256_storeu_ps(dst, _mm256_and_ps(_mm256_loadu_ps(t), _mm256_castsi256_ps(mask)));
}
template <ListBuildPath kPath>
SL_INLINE unsigned lanes_positive(const float* x) {
  return unsigned(_mm256_movemask_ps(_mm256_cmp_ps(_mm256_loadu_ps(x), _mm256_setzero_ps(), _CMP_GT_OQ)));
}

#include "core/list_tile_raster.inc"

unsigned slab8_box(const float* const o[3], const float* const inv[3], std::size_t i, const Box3& b, float* t0,
                   float* t1) {
  return slab8<false>(o, inv, i, &b.lo.x, &b.hi.x, t0, t1);
}
unsigned slab8_box_shared(const float* const inv[3], std::size_t i, const vec3& origin, const Box3& b, float* t0,
                          float* t1) {
  float lo_o[3], hi_o[3];
  for (int a = 0; a < 3; ++a) {
    lo_o[a] = b.lo[a] - origin[a];
    hi_o[a] = b.hi[a] - origin[a];
  }
  return slab8<true>(nullptr, inv, i, lo_o, hi_o, t0, t1);
}

}  // namespace lanes8
#if defined(__clang__)
#pragma clang attribute pop
#else
#pragma GCC pop_options
#endif

#endif

}  // namespace

namespace detail {

unsigned slab8(const float* const o[3], const float* const inv[3], std::size_t i, const Box3& b, float* t0, float* t1) {
  SL_CHECK(list_build_lanes8());
#if SL_AVX2_SLAB
  return lanes8::slab8_box(o, inv, i, b, t0, t1);
#else
  return 0u;
#endif
}

unsigned slab8_shared(const float* const inv[3], std::size_t i, const vec3& origin, const Box3& b, float* t0,
                      float* t1) {
  SL_CHECK(list_build_lanes8());
#if SL_AVX2_SLAB
  return lanes8::slab8_box_shared(inv, i, origin, b, t0, t1);
#else
  return 0u;
#endif
}

}  // namespace detail

bool list_build_lanes8() {
#if SL_AVX2_SLAB
  static const bool available = __builtin_cpu_supports("avx2");
  return available;
#else
  return false;
#endif
}

namespace {

// kLanes8: the eight-lane rasterizer (Fast only).
template <ListBuildPath kPath, bool kLanes8>
void build_tile(const TileJob& job, const ScreenRect& tile, const std::vector<std::uint32_t>& entries,
                SegmentListStats& st) {
  SegmentListBuffer& out = job.out;
  const int w = tile.x1 - tile.x0 + 1;
  if (entries.empty()) {  // every pixel's list is written here, the empty ones too
    for (int y = tile.y0; y <= tile.y1; ++y) {
      std::fill_n(out.offsets.data() + out.pixel(tile.x0, y), w, 0u);
      std::fill_n(out.counts.data() + out.pixel(tile.x0, y), w, 0u);
    }
    return;
  }
  thread_local TileScratch s;
  detail::tile_rays(job.gen, tile, s.origin, s.inv_dir);
  if (s.exits.size() < std::size_t(job.depth) * kTilePixels) s.exits.resize(std::size_t(job.depth) * kTilePixels);
  std::uint64_t tests = 0;
  std::size_t total = 0;  // the tile's events
  for (;;) {
    if (s.events.size() < std::size_t(s.capacity) * kTilePixels) s.events.resize(std::size_t(s.capacity) * kTilePixels);
    tests = 0;
#if SL_AVX2_SLAB
    if constexpr (kLanes8) {
      lanes8::rasterize_tile<kPath>(job, tile, entries, s, tests);
    } else {
      lanes4::rasterize_tile<kPath>(job, tile, entries, s, tests);
    }
#else
    lanes4::rasterize_tile<kPath>(job, tile, entries, s, tests);
#endif
    std::uint32_t words = 0;
    total = 0;
    for (int k = 0; k < kTilePixels; ++k) {
      words |= s.count[k];
      total += s.count[k];
    }
    if (!(words & kListOverflow)) break;
    SL_CHECK(s.capacity < (1u << 30));
    s.capacity *= 2;  // a list outgrew the scratch: the tile again, with room for it (and kept so)
  }
  st.slab_tests += tests;
  // Straight into the buffer: the tile's lists back to back, pixel by pixel; an empty list gets
  // offset 0 and count 0. The counts to the stats per tile: events, lists, the longest, and the
  // segments (a list's events, but for a closing INVALID one).
  std::uint32_t at = 0;
  RayEvent* const dst = total > 0 ? job.arena.reserve(total, at) : nullptr;
  std::uint32_t run = 0, lists = 0, closed = 0, longest = 0;
  for (int y = tile.y0; y <= tile.y1; ++y) {
    std::uint32_t* const offsets = out.offsets.data() + out.pixel(tile.x0, y);
    std::uint32_t* const counts = out.counts.data() + out.pixel(tile.x0, y);
    const int k0 = (y - tile.y0) * T;
    for (int x = 0; x < w; ++x) {
      const std::uint32_t c = s.count[k0 + x];
      counts[x] = c;
      offsets[x] = c != 0u ? at + run : 0u;
      if (c == 0u) continue;
      const RayEvent* const src = s.events.data() + std::size_t(k0 + x) * s.capacity;
      copy_events(dst + run, src, c, total - run);  // the scratch holds capacity >= 8 events a pixel
      run += c;
      ++lists;
      closed += src[c - 1].cls == std::uint8_t(OccupancyClass::Invalid) ? 1u : 0u;
      longest = std::max(longest, c);
    }
  }
  st.lists += lists;
  st.events += total;
  st.segments += total - closed;
  st.max_events = std::max(st.max_events, longest);
}

}  // namespace

SegmentListStats build_segment_lists(const OccupancyGeometry& geometry, std::span<const VisibilityEntry> order,
                                     const RayGenerator& gen, SegmentListBuffer& out, float eps, ListBuildPath path) {
  out.reshape(gen.width, gen.height);  // build_tile writes every pixel
  std::uint32_t depth = 0;
  thread_local std::vector<EntryRec> entries_kept;  // per calling thread, kept between frames
  std::vector<EntryRec>& entries = entries_kept;    // (the workers see it through this reference)
  entry_records(geometry, order, gen, entries, depth);
  EventArena arena(out);
  const TileJob job{entries, gen, depth, eps, arena, out};
  const bool lanes8 = path == ListBuildPath::Fast && list_build_lanes8();
  const SegmentListStats st = for_each_tile(
      gen, entries.size(), [&](std::size_t i) -> const ScreenRect& { return entries[i].rect; },
      [&](const ScreenRect& tile, const std::vector<std::uint32_t>& entries, SegmentListStats& s) {
        if (path == ListBuildPath::Scalar) {
          build_tile<ListBuildPath::Scalar, false>(job, tile, entries, s);
        } else if (lanes8) {
          build_tile<ListBuildPath::Fast, true>(job, tile, entries, s);
        } else {
          build_tile<ListBuildPath::Fast, false>(job, tile, entries, s);
        }
      });
  arena.finish();
  return st;
}

SegmentListStats build_segment_lists_reference(const OccupancyGeometry& geometry,
                                               std::span<const VisibilityEntry> order, const RayGenerator& gen,
                                               SegmentListBuffer& out, float eps, std::uint32_t capacity) {
  out.reset(gen.width, gen.height);
  EventArena arena(out);
  const SegmentListStats st = parallel_reduce(
      0, gen.height, 1, SegmentListStats{},
      [&](int row0, int row1, SegmentListStats s) {
        ListBlock block;
        std::vector<RayEvent> list(capacity > 0u ? capacity : kMaxEvents);
        for (int y = row0; y != row1; ++y) {
          block.clear();
          for (int x = 0; x < gen.width; ++x) {
            const Ray ray = gen.ray(x, y);
            std::uint32_t count = 0;
            for (;;) {
              count = 0;
              float t_seen = kNoEventYet;
              for (const VisibilityEntry& v : order) {
                const OccupancyBox& b = geometry.boxes[v.box];
                add_box_event(list.data(), count, t_seen, std::uint32_t(list.size()), ray, b.box,
                              v.face == Face::Front, b.cls, b.parent_cls, eps);
              }
              if (capacity > 0u || !(count & kListOverflow)) break;
              list.resize(2 * list.size());  // unbounded: the pixel again with room for its list
            }
            block.add(out.pixel(x, y), list.data(), count);
          }
          block.commit(arena, out, s);
        }
        return s;
      },
      sum_stats);
  arena.finish();
  return st;
}

SegmentListStats build_bbox_lists(std::span<const OccupancyBox> all_boxes, const RayGenerator& gen,
                                  SegmentListBuffer& out) {
  out.reset(gen.width, gen.height);
  std::vector<OccupancyBox> boxes;
  for (const OccupancyBox& b : all_boxes) {
    if (b.cls != OccupancyClass::Empty) boxes.push_back(b);
  }
  const std::vector<ScreenRect> rects = box_rects(boxes, gen);
  EventArena arena(out);
  const SegmentListStats st = for_each_tile(
      gen, boxes.size(), [&](std::size_t i) -> const ScreenRect& { return rects[i]; },
      [&](const ScreenRect& tile, const std::vector<std::uint32_t>& items, SegmentListStats& s) {
        if (items.empty()) return;  // the buffer's lists start empty
        thread_local ListBlock block;
        block.clear();
        for (int y = tile.y0; y <= tile.y1; ++y) {
          for (int x = tile.x0; x <= tile.x1; ++x) {
            const Ray ray = gen.ray(x, y);
            float first = HUGE_VALF, last = -HUGE_VALF;
            bool unknown = false;
            for (std::uint32_t i : items) {
              const ScreenRect& r = rects[i];
              if (x < r.x0 || x > r.x1 || y < r.y0 || y > r.y1) continue;
              const Interval iv = intersect(ray, boxes[i].box);
              if (iv.empty() || !(iv.t1 > 0.0f)) continue;
              first = std::min(first, std::max(iv.t0, 0.0f));
              last = std::max(last, iv.t1);
              unknown = unknown || boxes[i].cls == OccupancyClass::Unknown;
            }
            if (!(last > first)) continue;
            const OccupancyClass cls = unknown ? OccupancyClass::Unknown : OccupancyClass::NonEmpty;
            const RayEvent ev[2] = {detail::make_event(first, EventType::Entry, cls),
                                    detail::make_event(last, EventType::Exit, OccupancyClass::Invalid)};
            block.add(out.pixel(x, y), ev, 2u);
          }
        }
        block.commit(arena, out, s);
      });
  arena.finish();
  return st;
}

SegmentListStats compact_fixed_lists(const RayEvent* events, const std::uint32_t* counts, std::uint32_t capacity,
                                     int width, int height, SegmentListBuffer& out) {
  out.reset(width, height);
  EventArena arena(out);
  const SegmentListStats st = parallel_reduce(
      0, height, 1, SegmentListStats{},
      [&](int row0, int row1, SegmentListStats s) {
        for (int y = row0; y != row1; ++y) {  // a row's lists back to back
          const std::size_t p0 = out.pixel(0, y), p1 = p0 + std::size_t(width);
          std::size_t total = 0;
          for (std::size_t p = p0; p < p1; ++p) total += counts[p] & kListCountMask;
          std::uint32_t at = 0;
          RayEvent* const dst = arena.reserve(total, at);
          std::uint32_t run = 0;
          for (std::size_t p = p0; p < p1; ++p) {
            const std::uint32_t c = counts[p] & kListCountMask;
            std::copy_n(events + p * capacity, c, dst + run);
            out.offsets[p] = at + run;
            out.counts[p] = counts[p];
            count_list(s, dst + run, counts[p]);
            run += c;
          }
        }
        return s;
      },
      sum_stats);
  arena.finish();
  return st;
}

}  // namespace sl
