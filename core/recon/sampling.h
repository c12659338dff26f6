// Voxel fetch and trilinear sampling by the conventions of DESIGN.md "Ray casting": voxel i's value sits at its
// centre, world (i + 0.5) * spacing; sampling clamps to the edge voxels.
#pragma once

#include <cstdint>
#include <cstring>
#include <type_traits>

#include "core/util/config.h"

#if !defined(__CUDA_ARCH__) && defined(__SSE2__) && !defined(SL_NO_SSE)
#include <emmintrin.h>
#define SL_SSE_TRILERP 1
#else
#define SL_SSE_TRILERP 0
#endif
#include "core/recon/gradient.h"
#include "core/util/math.h"

namespace sl {

// Which code blends the x-rows: Fast is the SSE path where it applies (x86 hosts, 8- and 16-bit
// voxels) and the scalar one elsewhere; Scalar is always the scalar twin, the only path on the device.
// Renderers use Fast; tests/core/cast/sampling_simd_test.cpp checks that both give the same bits
// (STYLE.md #15).
enum class TrilerpPath { Fast, Scalar };

// Trilinear blend of 2x2x2 voxels given as four x-rows (row[0] holds x0, row[dx] holds x1; dx is 0 at
// the last voxel of a row, where clamping repeats the edge). The dense sampler and the brick-slot
// sampler both blend through this one function, so their results are bit-identical. On x86 hosts the
// four x-lerps run as one 4-wide SSE operation: lane for lane the same IEEE single-precision
// subtract, multiply and add as the scalar code (no FMA contraction on this target), so the value is
// exactly the scalar one; only the instruction count drops.
template <TrilerpPath kPath = TrilerpPath::Fast, class T>
SL_HOST_DEVICE SL_INLINE float trilerp(const T* r00, const T* r01, const T* r10, const T* r11, int dx, float fx,
                                       float fy, float fz) {
  float c00, c01, c10, c11;
#if SL_SSE_TRILERP
  if constexpr (kPath == TrilerpPath::Fast && sizeof(T) <= 2 && !std::is_floating_point_v<T>) {
    __m128 a, b;
    if (dx == 1) {
      // Each row's pair (x0, x1) is adjacent in memory: four small loads, widened to 32-bit lanes.
      std::uint32_t p00, p01, p10, p11;
      if constexpr (sizeof(T) == 1) {
        // pinsrw from memory: four 16-bit loads straight into lanes 0..3.
        std::uint16_t q0, q1, q2, q3;
        std::memcpy(&q0, r00, 2);
        std::memcpy(&q1, r01, 2);
        std::memcpy(&q2, r10, 2);
        std::memcpy(&q3, r11, 2);
        // All eight voxels equal (background, uniform interiors: most samples of sparse data): every
        // lerp returns its first operand exactly, so the blend is that value.
        if (q0 == q1 && q1 == q2 && q2 == q3 && (q0 & 0xFFu) == (q0 >> 8)) return float(q0 & 0xFFu);
        __m128i bytes = _mm_cvtsi32_si128(int(q0));
        bytes = _mm_insert_epi16(bytes, int(q1), 1);
        bytes = _mm_insert_epi16(bytes, int(q2), 2);
        bytes = _mm_insert_epi16(bytes, int(q3), 3);
        const __m128i zero = _mm_setzero_si128();
        const __m128i words = _mm_unpacklo_epi8(bytes, zero);
        const __m128 lo = _mm_cvtepi32_ps(_mm_unpacklo_epi16(words, zero));  // r00x0 r00x1 r01x0 r01x1
        const __m128 hi = _mm_cvtepi32_ps(_mm_unpackhi_epi16(words, zero));  // r10x0 r10x1 r11x0 r11x1
        a = _mm_shuffle_ps(lo, hi, _MM_SHUFFLE(2, 0, 2, 0));
        b = _mm_shuffle_ps(lo, hi, _MM_SHUFFLE(3, 1, 3, 1));
      } else {
        std::memcpy(&p00, r00, 4);
        std::memcpy(&p01, r01, 4);
        std::memcpy(&p10, r10, 4);
        std::memcpy(&p11, r11, 4);
        if (p00 == p01 && p01 == p10 && p10 == p11 && (p00 & 0xFFFFu) == (p00 >> 16)) return float(p00 & 0xFFFFu);
        const __m128i words = _mm_setr_epi32(int(p00), int(p01), int(p10), int(p11));
        const __m128i zero = _mm_setzero_si128();
        const __m128 lo = _mm_cvtepi32_ps(_mm_unpacklo_epi16(words, zero));
        const __m128 hi = _mm_cvtepi32_ps(_mm_unpackhi_epi16(words, zero));
        a = _mm_shuffle_ps(lo, hi, _MM_SHUFFLE(2, 0, 2, 0));
        b = _mm_shuffle_ps(lo, hi, _MM_SHUFFLE(3, 1, 3, 1));
      }
    } else {
      a = _mm_setr_ps(float(r00[0]), float(r01[0]), float(r10[0]), float(r11[0]));
      b = a;
    }
    const __m128 c = _mm_add_ps(a, _mm_mul_ps(_mm_set1_ps(fx), _mm_sub_ps(b, a)));
    alignas(16) float cv[4];
    _mm_store_ps(cv, c);
    c00 = cv[0];
    c01 = cv[1];
    c10 = cv[2];
    c11 = cv[3];
  } else
#endif
  {
    c00 = float(r00[0]) + fx * (float(r00[dx]) - float(r00[0]));
    c01 = float(r01[0]) + fx * (float(r01[dx]) - float(r01[0]));
    c10 = float(r10[0]) + fx * (float(r10[dx]) - float(r10[0]));
    c11 = float(r11[0]) + fx * (float(r11[dx]) - float(r11[0]));
  }
  const float c0 = c00 + fy * (c01 - c00);
  const float c1 = c10 + fy * (c11 - c10);
  return c0 + fz * (c1 - c0);
}

// Continuous voxel coordinate of world point p (voxel centres at integers), clamped to the volume:
// the trilinear cell of the sample is int() of it (u >= 0, so int() == floor). glm::clamp's order of
// comparisons (min(max(u, 0), dims - 1)), spelled out: glm's clamp was an out-of-line call per sample.
// DenseGrid::sample and the voxel mask (core/occupancy/fine_occupancy.h) both take the cell from here, so they
// agree on it bit for bit.
// `hi` is vec3(dims - 1), which a caller may hold precomputed (the conversions cost about as much as
// the clamp).
SL_HOST_DEVICE SL_INLINE vec3 clamped_voxel_coord(const vec3& p, const vec3& inv_spacing, const vec3& hi) {
  // Per component by name: a loop over u[a] keeps glm's run-time indexing.
  // The comparisons are in the operand order of SSE's maxss / minss, so each bound is one instruction
  // (glm's order is not: -0 and NaN differ). Values are those of glm::clamp except that -0 becomes +0
  // (the same cell and blend) and a NaN coordinate becomes 0 (int(NaN) would be undefined).
  const auto clamp = [](float x, float h) {
    x = 0.0f < x ? x : 0.0f;
    return x < h ? x : h;
  };
  return vec3(clamp(p.x * inv_spacing.x - 0.5f, hi.x), clamp(p.y * inv_spacing.y - 0.5f, hi.y),
              clamp(p.z * inv_spacing.z - 0.5f, hi.z));
}
SL_HOST_DEVICE SL_INLINE vec3 clamped_voxel_coord(const vec3& p, const vec3& inv_spacing, const ivec3& dims) {
  return clamped_voxel_coord(p, inv_spacing, vec3(dims - 1));
}

// Dense volume of element type T, x fastest. Plain data, copyable to a device.
template <class T>
struct DenseGrid {
  const T* data = nullptr;
  ivec3 dims{0, 0, 0};
  vec3 inv_spacing{1.0f};

  SL_HOST_DEVICE float fetch(int x, int y, int z) const {
    return float(data[(std::int64_t(z) * dims.y + y) * std::int64_t(dims.x) + x]);
  }
  SL_HOST_DEVICE std::uint32_t fetch_label(int x, int y, int z) const {
    return std::uint32_t(data[(std::int64_t(z) * dims.y + y) * std::int64_t(dims.x) + x]);
  }

  // Trilinear sample at world position p (kPath: see TrilerpPath).
  template <TrilerpPath kPath = TrilerpPath::Fast>
  SL_HOST_DEVICE SL_INLINE float sample(const vec3& p) const {
    return sample_coord<kPath>(clamped_voxel_coord(p, inv_spacing, dims));
  }
  // The same from the clamped voxel coordinate u of the sample (clamped_voxel_coord), for a caller
  // that has it already (the voxel mask's test computes it).
  template <TrilerpPath kPath = TrilerpPath::Fast>
  SL_HOST_DEVICE SL_INLINE float sample_coord(const vec3& u) const {
    const int x0 = int(u.x), y0 = int(u.y), z0 = int(u.z);  // u >= 0, so int() == floor
    const float fx = u.x - float(x0), fy = u.y - float(y0), fz = u.z - float(z0);
    const std::int64_t sx = dims.x, sxy = std::int64_t(dims.x) * dims.y;
    // The +1 neighbours as offsets (0 at the last voxel, where clamping repeats the edge): one
    // multiply per axis for the four rows.
    const int dx = x0 + 1 < dims.x ? 1 : 0;
    const std::int64_t dy = y0 + 1 < dims.y ? sx : 0;
    const std::int64_t dz = z0 + 1 < dims.z ? sxy : 0;
    const T* r00 = data + (z0 * sxy + y0 * sx + x0);
    return trilerp<kPath>(r00, r00 + dy, r00 + dz, r00 + dz + dy, dx, fx, fy, fz);
  }

  // Voxel v's value with v clamped to the volume (the corner values exact iso reads per cell: the
  // trilinear sample at a voxel centre, without the blend).
  SL_HOST_DEVICE SL_INLINE float voxel_clamped(const ivec3& v) const {
    const int x = v.x < 0 ? 0 : (v.x >= dims.x ? dims.x - 1 : v.x);
    const int y = v.y < 0 ? 0 : (v.y >= dims.y ? dims.y - 1 : v.y);
    const int z = v.z < 0 ? 0 : (v.z >= dims.z ? dims.z - 1 : v.z);
    return fetch(x, y, z);
  }

  // The voxel containing world position p (nearest-neighbour lookup for labels), clamped. Truncation
  // equals floor after the clamp (a negative coordinate becomes 0 either way) and, unlike floorf,
  // is one instruction on baseline x86-64.
  SL_HOST_DEVICE SL_INLINE std::uint32_t label_at(const vec3& p) const {
    const vec3 u = p * inv_spacing;
    int x = int(u.x), y = int(u.y), z = int(u.z);
    x = x < 0 ? 0 : (x >= dims.x ? dims.x - 1 : x);
    y = y < 0 ? 0 : (y >= dims.y ? dims.y - 1 : y);
    z = z < 0 ? 0 : (z >= dims.z ? dims.z - 1 : z);
    return fetch_label(x, y, z);
  }

  // Central-difference gradient in world units, one voxel apart.
  SL_HOST_DEVICE vec3 gradient(const vec3& p, const vec3& spacing) const {
    return central_difference_gradient(p, spacing, [this](const vec3& q) { return sample(q); });
  }
};

}  // namespace sl
