// The tile rasterizer of the CPU list builder (core/lists/list_tile_raster.h): the lanes (slab tests, lane
// masks) four and eight pixels wide, Alg. 4-5's events per hit pixel, and the copy of a tile's lists
// into the frame's buffer.
#include "core/lists/list_tile_raster.h"

#include <algorithm>
#include <bit>
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

namespace {

using detail::ListEntry;
using detail::ListTileJob;

constexpr int T = detail::kListTile;
constexpr int kTilePixels = T * T;
static_assert(kTilePixels % 64 == 0 && T % 4 == 0, "a tile's hits fill 64-bit words; no group of four straddles two");

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

#include "core/lists/list_tile_raster.inc"

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

#include "core/lists/list_tile_raster.inc"

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
void build_tile(const ListTileJob& job, const ScreenRect& tile, const std::vector<std::uint32_t>& entries,
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

namespace detail {

void build_list_tile(const ListTileJob& job, const ScreenRect& tile, const std::vector<std::uint32_t>& entries,
                     SegmentListStats& st, ListBuildPath path) {
  if (path == ListBuildPath::Scalar) {
    build_tile<ListBuildPath::Scalar, false>(job, tile, entries, st);
  } else if (path == ListBuildPath::Fast && list_build_lanes8()) {
    build_tile<ListBuildPath::Fast, true>(job, tile, entries, st);
  } else {
    build_tile<ListBuildPath::Fast, false>(job, tile, entries, st);
  }
}

}  // namespace detail

}  // namespace sl
