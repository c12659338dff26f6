// The AVX2 batch of core/cast/sample_batch.h. Compiled for the baseline target; only the functions marked
// target("avx2") use AVX2, and they run only where the CPU has it (sample_batch_available). Without
// "fma" in the target the compiler cannot contract a multiply and an add, so every lane rounds as the
// scalar code does.
#include "core/cast/sample_batch.h"

#include "core/cast/bricked_volume.h"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#define SL_BATCH_AVX2 1
#else
#define SL_BATCH_AVX2 0
#endif

namespace sl {

#if SL_BATCH_AVX2

bool sample_batch_available() {
  static const bool available = __builtin_cpu_supports("avx2");
  return available;
}

bool sample_batch_fits(const DvrBatchArgs& a) {
  constexpr std::int64_t kLimit = std::int64_t(1) << 30;  // 32-bit lane offsets with headroom
  if (a.elem_size != 1 && a.elem_size != 2) return false;
  if (a.dims.x <= 0 || a.dims.y <= 0 || a.dims.z <= 0 || a.bytes < 4 || a.bytes > kLimit) return false;
  if (std::int64_t(a.dims.x) * a.dims.y * a.dims.z * a.elem_size != a.bytes) return false;
  if (a.mask_bits && std::int64_t(a.mask_plane_words) * a.dims.z * 2 > kLimit) return false;
  if (a.slot && a.bricks) return false;
  if (a.bricks && (!BrickedVolume::supported(a.dims, a.elem_size) || a.brick_counts != BrickedVolume::brick_counts(a.dims))) {
    return false;
  }
  return a.tf_table != nullptr && a.tf_size >= 2;
}

namespace {

#define SL_AVX2 __attribute__((target("avx2"))) inline

// The clamped voxel coordinate along one axis at the lanes' t (Ray::at, clamped_voxel_coord).
SL_AVX2 __m256 coord(__m256 t, float o, float d, float inv, float hi) {
  const __m256 p = _mm256_add_ps(_mm256_set1_ps(o), _mm256_mul_ps(t, _mm256_set1_ps(d)));
  const __m256 u = _mm256_sub_ps(_mm256_mul_ps(p, _mm256_set1_ps(inv)), _mm256_set1_ps(0.5f));
  // maxps / minps return the second operand on NaN and on equal zeros: 0 < x ? x : 0, x < h ? x : h.
  return _mm256_min_ps(_mm256_max_ps(u, _mm256_setzero_ps()), _mm256_set1_ps(hi));
}

// One x-row of the lanes' cells, blended along x (trilerp): a 4-byte gather at byte offset `o` holds
// (x0, x0 + 1); the last voxel of a row repeats itself (has_dx clear).
template <int kElem>
SL_AVX2 __m256 row(const int* base, __m256i o, __m256i live, __m256i has_dx, __m256 fx) {
  const __m256i lo_mask = _mm256_set1_epi32(kElem == 1 ? 0xFF : 0xFFFF);
  const __m256i g = _mm256_mask_i32gather_epi32(_mm256_setzero_si256(), base, o, live, 1);
  const __m256i v0 = _mm256_and_si256(g, lo_mask);
  const __m256i v1 = _mm256_and_si256(_mm256_srli_epi32(g, 8 * kElem), lo_mask);
  const __m256 c0 = _mm256_cvtepi32_ps(v0);
  const __m256 c1 = _mm256_cvtepi32_ps(_mm256_blendv_epi8(v0, v1, has_dx));
  return _mm256_add_ps(c0, _mm256_mul_ps(fx, _mm256_sub_ps(c1, c0)));
}

// The lanes' sample positions: t = t_entry + float(k) * dt; p = origin + t * dir (Ray::at);
// u = clamp(p * inv_spacing - 0.5, 0, hi), and the voxel x0 = trunc(u) per axis.
struct Lanes {
  __m256 t;
  __m256 ux, uy, uz;
  __m256i x0, y0, z0;
};

SL_AVX2 Lanes lanes_at(const DvrBatchArgs& a, __m256 kf) {
  const __m256 t = _mm256_add_ps(_mm256_set1_ps(a.t_entry), _mm256_mul_ps(kf, _mm256_set1_ps(a.dt)));
  Lanes l;
  l.t = t;
  l.ux = coord(t, a.origin.x, a.dir.x, a.inv_spacing.x, a.hi.x);
  l.uy = coord(t, a.origin.y, a.dir.y, a.inv_spacing.y, a.hi.y);
  l.uz = coord(t, a.origin.z, a.dir.z, a.inv_spacing.z, a.hi.z);
  l.x0 = _mm256_cvttps_epi32(l.ux);
  l.y0 = _mm256_cvttps_epi32(l.uy);
  l.z0 = _mm256_cvttps_epi32(l.uz);
  return l;
}

SL_AVX2 __m256i first_lanes(int n) {
  return _mm256_cmpgt_epi32(_mm256_set1_epi32(n), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
}

SL_AVX2 __m256 consecutive(int k) {
  return _mm256_cvtepi32_ps(_mm256_add_epi32(_mm256_set1_epi32(k), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7)));
}

// The 32-bit word and the bit in it of the voxel-mask bit of the lanes' voxels (x, y, z), in the mask's
// own voxels: in core, the 64-bit word z * plane + y * row + (x >> 6), bit x & 63, read as its 32-bit
// half x >> 5 of the little-endian pair, bit x & 31; a slot's packed mask, bit (z * dims.y + y) * dims.x + x.
template <bool kSlot>
SL_AVX2 void mask_word(const DvrBatchArgs& a, __m256i x, __m256i y, __m256i z, __m256i& word, __m256i& bit) {
  if constexpr (kSlot) {
    const __m256i b = _mm256_add_epi32(
        _mm256_mullo_epi32(_mm256_add_epi32(_mm256_mullo_epi32(z, _mm256_set1_epi32(a.dims.y)), y),
                           _mm256_set1_epi32(a.dims.x)),
        x);
    word = _mm256_srli_epi32(b, 5);
    bit = _mm256_and_si256(b, _mm256_set1_epi32(31));
  } else {
    word = _mm256_add_epi32(_mm256_add_epi32(_mm256_mullo_epi32(z, _mm256_set1_epi32(2 * a.mask_plane_words)),
                                             _mm256_mullo_epi32(y, _mm256_set1_epi32(2 * a.mask_row_words))),
                            _mm256_srli_epi32(x, 5));
    bit = _mm256_and_si256(x, _mm256_set1_epi32(31));
  }
}

// The lanes' voxels in the data's (and the mask's) own voxels: less a slot's first voxel.
template <bool kSlot>
SL_AVX2 void local_voxels(const DvrBatchArgs& a, const Lanes& l, __m256i& x, __m256i& y, __m256i& z) {
  if constexpr (kSlot) {
    x = _mm256_sub_epi32(l.x0, _mm256_set1_epi32(a.first.x));
    y = _mm256_sub_epi32(l.y0, _mm256_set1_epi32(a.first.y));
    z = _mm256_sub_epi32(l.z0, _mm256_set1_epi32(a.first.z));
  } else {
    x = l.x0;
    y = l.y0;
    z = l.z0;
  }
}

// The live lanes whose voxel-mask bit is set (VoxelMaskView::visible_coord; SlotSampler::mask_visible).
template <bool kSlot>
SL_AVX2 __m256i mask_lanes(const DvrBatchArgs& a, const Lanes& l, __m256i live) {
  __m256i x, y, z, w, sh;
  local_voxels<kSlot>(a, l, x, y, z);
  mask_word<kSlot>(a, x, y, z, w, sh);
  const __m256i words =
      _mm256_mask_i32gather_epi32(_mm256_setzero_si256(), reinterpret_cast<const int*>(a.mask_bits), w, live, 4);
  const __m256i one = _mm256_set1_epi32(1);
  const __m256i bit = _mm256_and_si256(_mm256_srlv_epi32(words, sh), one);
  return _mm256_and_si256(live, _mm256_cmpeq_epi32(bit, one));
}

// The transfer function's opacity at the lanes' values v (TransferFunctionView::coord and alpha_at),
// and the batch's output.
SL_AVX2 int classify_lanes(const DvrBatchArgs& a, const Lanes& l, __m256i live, int visible, __m256 v,
                           DvrBatchOut& out) {
  const __m256 zero = _mm256_setzero_ps();
  __m256 x = _mm256_mul_ps(_mm256_sub_ps(v, _mm256_set1_ps(a.tf_vmin)), _mm256_set1_ps(a.tf_inv_step));
  const __m256 xm = _mm256_min_ps(x, _mm256_set1_ps(float(a.tf_size - 1)));  // x < last ? x : last
  x = _mm256_and_ps(_mm256_cmp_ps(x, zero, _CMP_GT_OQ), xm);                  // x > 0 ? that : 0 (NaN: 0)
  const __m256i i = _mm256_min_epi32(_mm256_cvttps_epi32(x), _mm256_set1_epi32(a.tf_size - 2));
  const __m256 f = _mm256_sub_ps(x, _mm256_cvtepi32_ps(i));
  const __m256 live_ps = _mm256_castsi256_ps(live);
  __m256 w0, w1;
  if (a.tf_alpha) {
    w0 = _mm256_mask_i32gather_ps(zero, a.tf_alpha, i, live_ps, 4);
    w1 = _mm256_mask_i32gather_ps(zero, a.tf_alpha + 1, i, live_ps, 4);
  } else {
    const __m256i wi = _mm256_add_epi32(_mm256_slli_epi32(i, 2), _mm256_set1_epi32(3));
    w0 = _mm256_mask_i32gather_ps(zero, a.tf_table, wi, live_ps, 4);
    w1 = _mm256_mask_i32gather_ps(zero, a.tf_table + 4, wi, live_ps, 4);
  }
  const __m256 alpha = _mm256_add_ps(w0, _mm256_mul_ps(f, _mm256_sub_ps(w1, w0)));

  _mm256_store_ps(out.t, l.t);
  _mm256_store_ps(out.v, v);
  _mm256_store_ps(out.alpha, alpha);
  _mm256_store_ps(out.f, f);
  _mm256_store_si256(reinterpret_cast<__m256i*>(out.i), i);
  out.opaque = unsigned(_mm256_movemask_ps(_mm256_cmp_ps(alpha, zero, _CMP_GT_OQ)) & visible);
  return visible;
}

// Value and opacity of the live lanes; -1 when a lane's last row would read past the volume (never
// from bricks, whose allocation has room for the last gather). The gathers fetch the lanes of `fetch`
// (a superset of `live`): under the voxel mask, all the batch's positions, so that they do not wait for
// the mask's gather (their lane masks would depend on its result); only `live` lanes are reported.
template <int kElem, bool kSlot>
SL_AVX2 int sample_lanes(const DvrBatchArgs& a, const Lanes& l, __m256i fetch, __m256i live, DvrBatchOut& out) {
  const __m256 ux = l.ux, uy = l.uy, uz = l.uz;
  const int visible = _mm256_movemask_ps(_mm256_castsi256_ps(live));
  if (visible == 0) {
    out.opaque = 0u;
    return 0;
  }

  // DenseGrid::sample_coord: the four x-rows of the cell, each one 4-byte gather holding (x0, x0 + 1),
  // blended along x, then y, then z.
  const __m256 fx = _mm256_sub_ps(ux, _mm256_cvtepi32_ps(l.x0));
  const __m256 fy = _mm256_sub_ps(uy, _mm256_cvtepi32_ps(l.y0));
  const __m256 fz = _mm256_sub_ps(uz, _mm256_cvtepi32_ps(l.z0));
  // The voxel indices into the data (a slot's: its own; a slot holds x0 + 1 in its apron, so the
  // clamps below never apply there).
  __m256i x0, y0, z0;
  local_voxels<kSlot>(a, l, x0, y0, z0);
  __m256i off, dy, dz, has_dx;
  const void* data;
  if (a.bricks) {
    // BrickedVolume: the cell's brick (x0 / 8, ...) holds all eight voxels, the apron the clamped edge.
    constexpr int E = BrickedVolume::kEdge;
    const __m256i seven = _mm256_set1_epi32(BrickedVolume::kCells - 1);
    const __m256i brick = _mm256_add_epi32(
        _mm256_mullo_epi32(_mm256_add_epi32(_mm256_mullo_epi32(_mm256_srli_epi32(z0, 3), _mm256_set1_epi32(a.brick_counts.y)),
                                            _mm256_srli_epi32(y0, 3)),
                           _mm256_set1_epi32(a.brick_counts.x)),
        _mm256_srli_epi32(x0, 3));
    const __m256i local = _mm256_add_epi32(
        _mm256_add_epi32(_mm256_mullo_epi32(_mm256_and_si256(z0, seven), _mm256_set1_epi32(E * E)),
                         _mm256_mullo_epi32(_mm256_and_si256(y0, seven), _mm256_set1_epi32(E))),
        _mm256_and_si256(x0, seven));
    off = _mm256_add_epi32(_mm256_mullo_epi32(brick, _mm256_set1_epi32(BrickedVolume::kVoxels)), local);
    dy = _mm256_set1_epi32(E * kElem);
    dz = _mm256_set1_epi32(E * E * kElem);
    has_dx = _mm256_set1_epi32(-1);
    data = a.bricks;
  } else {
    const __m256i one = _mm256_set1_epi32(1);
    const int sx = a.dims.x, sxy = a.dims.x * a.dims.y;
    has_dx = _mm256_cmpgt_epi32(_mm256_set1_epi32(a.dims.x), _mm256_add_epi32(x0, one));
    dy = _mm256_and_si256(_mm256_cmpgt_epi32(_mm256_set1_epi32(a.dims.y), _mm256_add_epi32(y0, one)),
                          _mm256_set1_epi32(sx * kElem));
    dz = _mm256_and_si256(_mm256_cmpgt_epi32(_mm256_set1_epi32(a.dims.z), _mm256_add_epi32(z0, one)),
                          _mm256_set1_epi32(sxy * kElem));
    off = _mm256_add_epi32(_mm256_add_epi32(_mm256_mullo_epi32(z0, _mm256_set1_epi32(sxy)),
                                            _mm256_mullo_epi32(y0, _mm256_set1_epi32(sx))),
                           x0);
    data = a.data;
  }
  if constexpr (kElem == 2) off = _mm256_slli_epi32(off, 1);
  const __m256i last = _mm256_add_epi32(off, _mm256_add_epi32(dy, dz));
  // A lane whose last row starts within 4 bytes of the end: the gather would read past the volume.
  if (!a.bricks && _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_and_si256(
                       fetch, _mm256_cmpgt_epi32(last, _mm256_set1_epi32(int(a.bytes - 4)))))) != 0) {
    return -1;
  }
  const int* base = static_cast<const int*>(data);
  const __m256 c00 = row<kElem>(base, off, fetch, has_dx, fx);
  const __m256 c01 = row<kElem>(base, _mm256_add_epi32(off, dy), fetch, has_dx, fx);
  const __m256 c10 = row<kElem>(base, _mm256_add_epi32(off, dz), fetch, has_dx, fx);
  const __m256 c11 = row<kElem>(base, last, fetch, has_dx, fx);
  const __m256 c0 = _mm256_add_ps(c00, _mm256_mul_ps(fy, _mm256_sub_ps(c01, c00)));
  const __m256 c1 = _mm256_add_ps(c10, _mm256_mul_ps(fy, _mm256_sub_ps(c11, c10)));
  return classify_lanes(a, l, fetch, visible, _mm256_add_ps(c0, _mm256_mul_ps(fz, _mm256_sub_ps(c1, c0))), out);
}

template <int kElem, bool kSlot>
__attribute__((target("avx2"))) int dvr_batch_avx2(const DvrBatchArgs& a, int k, int n, DvrBatchOut& out) {
  const Lanes l = lanes_at(a, consecutive(k));
  const __m256i live = first_lanes(n);
  return sample_lanes<kElem, kSlot>(a, l, live, a.mask_bits ? mask_lanes<kSlot>(a, l, live) : live, out);
}

template <int kElem, bool kSlot>
__attribute__((target("avx2"))) int dvr_batch_at_avx2(const DvrBatchArgs& a, const int* ks, int n, DvrBatchOut& out) {
  const __m256i kv = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(ks));
  const __m256i live = first_lanes(n);
  return sample_lanes<kElem, kSlot>(a, lanes_at(a, _mm256_cvtepi32_ps(kv)), live, live, out);
}

// For each 8-bit lane mask, the set lanes' numbers in ascending order, 4 bits each (compaction).
struct CompactTable {
  std::uint32_t packed[256];
  constexpr CompactTable() : packed{} {
    for (int m = 0; m < 256; ++m) {
      std::uint32_t p = 0;
      int n = 0;
      for (int j = 0; j < 8; ++j) {
        if (m & (1 << j)) p |= std::uint32_t(j) << (4 * n++);
      }
      packed[m] = p;
    }
  }
};
constexpr CompactTable kCompact;

template <bool kSlot>
__attribute__((target("avx2,popcnt"))) int dvr_mask_scan_avx2(const DvrBatchArgs& a, const SampleSpan* spans,
                                                              int n, int& s_io, int& k_io, int* ks, int queued,
                                                              int want) {
  // The per-axis constants once; the lanes' positions are lanes_at's operations on them.
  const __m256 t_entry = _mm256_set1_ps(a.t_entry), dt = _mm256_set1_ps(a.dt);
  const __m256 ox = _mm256_set1_ps(a.origin.x), oy = _mm256_set1_ps(a.origin.y), oz = _mm256_set1_ps(a.origin.z);
  const __m256 dx = _mm256_set1_ps(a.dir.x), dy = _mm256_set1_ps(a.dir.y), dz = _mm256_set1_ps(a.dir.z);
  const __m256 ix = _mm256_set1_ps(a.inv_spacing.x), iy = _mm256_set1_ps(a.inv_spacing.y),
               iz = _mm256_set1_ps(a.inv_spacing.z);
  const __m256 hx = _mm256_set1_ps(a.hi.x), hy = _mm256_set1_ps(a.hi.y), hz = _mm256_set1_ps(a.hi.z);
  const __m256 half = _mm256_set1_ps(0.5f), zero = _mm256_setzero_ps();
  const __m256i plane = _mm256_set1_epi32(kSlot ? a.dims.y : 2 * a.mask_plane_words),
                row = _mm256_set1_epi32(kSlot ? a.dims.x : 2 * a.mask_row_words);
  const __m256i fx = _mm256_set1_epi32(a.first.x), fy = _mm256_set1_epi32(a.first.y), fz = _mm256_set1_epi32(a.first.z);
  const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7), one = _mm256_set1_epi32(1),
                low5 = _mm256_set1_epi32(31), nib = _mm256_set1_epi32(15);
  const __m256i shifts = _mm256_setr_epi32(0, 4, 8, 12, 16, 20, 24, 28);
  const int* bits = reinterpret_cast<const int*>(a.mask_bits);
  // The level-adaptive grid's positions: multiples of 2^stride, eight of them per step.
  const int stride = a.stride_log2, round = (1 << stride) - 1;
  const __m256i lane_k = _mm256_slli_epi32(lane, stride);
  int s = s_io, k = (k_io + round) & ~round;
  while (s < n && queued < want) {
    const int k1 = spans[s].k1;
    while (k < k1 && queued < want) {
      const __m256i kv = _mm256_add_epi32(_mm256_set1_epi32(k), lane_k);
      const __m256 t = _mm256_add_ps(t_entry, _mm256_mul_ps(_mm256_cvtepi32_ps(kv), dt));
      const __m256 ux = _mm256_min_ps(
          _mm256_max_ps(_mm256_sub_ps(_mm256_mul_ps(_mm256_add_ps(ox, _mm256_mul_ps(t, dx)), ix), half), zero), hx);
      const __m256 uy = _mm256_min_ps(
          _mm256_max_ps(_mm256_sub_ps(_mm256_mul_ps(_mm256_add_ps(oy, _mm256_mul_ps(t, dy)), iy), half), zero), hy);
      const __m256 uz = _mm256_min_ps(
          _mm256_max_ps(_mm256_sub_ps(_mm256_mul_ps(_mm256_add_ps(oz, _mm256_mul_ps(t, dz)), iz), half), zero), hz);
      __m256i w, sh;
      if constexpr (kSlot) {
        // mask_word<true>, with the constants hoisted: bit (z * dims.y + y) * dims.x + x of the local voxel.
        const __m256i x0 = _mm256_sub_epi32(_mm256_cvttps_epi32(ux), fx);
        const __m256i b = _mm256_add_epi32(
            _mm256_mullo_epi32(_mm256_add_epi32(_mm256_mullo_epi32(_mm256_sub_epi32(_mm256_cvttps_epi32(uz), fz), plane),
                                                _mm256_sub_epi32(_mm256_cvttps_epi32(uy), fy)),
                               row),
            x0);
        w = _mm256_srli_epi32(b, 5);
        sh = _mm256_and_si256(b, low5);
      } else {
        const __m256i x0 = _mm256_cvttps_epi32(ux);
        w = _mm256_add_epi32(_mm256_add_epi32(_mm256_mullo_epi32(_mm256_cvttps_epi32(uz), plane),
                                              _mm256_mullo_epi32(_mm256_cvttps_epi32(uy), row)),
                             _mm256_srli_epi32(x0, 5));
        sh = _mm256_and_si256(x0, low5);
      }
      const __m256i live = _mm256_cmpgt_epi32(_mm256_set1_epi32(k1 - k), lane_k);
      const __m256i words = _mm256_mask_i32gather_epi32(_mm256_setzero_si256(), bits, w, live, 4);
      const __m256i bit = _mm256_and_si256(_mm256_srlv_epi32(words, sh), one);
      const int m = _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_and_si256(live, _mm256_cmpeq_epi32(bit, one))));
      if (m != 0) {
        const __m256i idx = _mm256_and_si256(_mm256_srlv_epi32(_mm256_set1_epi32(int(kCompact.packed[m])), shifts), nib);
        _mm256_storeu_si256(reinterpret_cast<__m256i*>(ks + queued), _mm256_permutevar8x32_epi32(kv, idx));
        queued += __builtin_popcount(unsigned(m));
      }
      k += 8 << stride;
    }
    if (k < k1) break;  // `want` queued
    if (++s < n) k = (spans[s].k0 + round) & ~round;
  }
  s_io = s;
  k_io = k;
  return queued;
}

}  // namespace

int dvr_batch(const DvrBatchArgs& a, int k, int n, DvrBatchOut& out) {
  if (a.slot) return a.elem_size == 1 ? dvr_batch_avx2<1, true>(a, k, n, out) : dvr_batch_avx2<2, true>(a, k, n, out);
  return a.elem_size == 1 ? dvr_batch_avx2<1, false>(a, k, n, out) : dvr_batch_avx2<2, false>(a, k, n, out);
}

int dvr_batch_at(const DvrBatchArgs& a, const int* ks, int n, DvrBatchOut& out) {
  if (a.slot) {
    return a.elem_size == 1 ? dvr_batch_at_avx2<1, true>(a, ks, n, out) : dvr_batch_at_avx2<2, true>(a, ks, n, out);
  }
  return a.elem_size == 1 ? dvr_batch_at_avx2<1, false>(a, ks, n, out) : dvr_batch_at_avx2<2, false>(a, ks, n, out);
}

int dvr_mask_scan_spans(const DvrBatchArgs& a, const SampleSpan* spans, int n, int& s, int& k, int* ks, int queued,
                        int want) {
  return a.slot ? dvr_mask_scan_avx2<true>(a, spans, n, s, k, ks, queued, want)
                : dvr_mask_scan_avx2<false>(a, spans, n, s, k, ks, queued, want);
}

#else

bool sample_batch_available() { return false; }
bool sample_batch_fits(const DvrBatchArgs&) { return false; }
int dvr_batch(const DvrBatchArgs&, int, int, DvrBatchOut&) { return -1; }
int dvr_batch_at(const DvrBatchArgs&, const int*, int, DvrBatchOut&) { return -1; }
int dvr_mask_scan_spans(const DvrBatchArgs&, const SampleSpan*, int n, int& s, int&, int*, int queued, int) {
  s = n;
  return queued;
}

#endif

}  // namespace sl
