// Uniform B-spline reconstruction (DESIGN.md "Ray casting"): the tri-quadratic and tri-cubic B-spline
// with the voxels as control points, voxel i's control point at its centre (continuous voxel coordinate
// u = world / voxel size - 0.5 = i). Both filters are approximating (a smoothed version of the data) and
// convex: the weights are non-negative and sum to one, so a reconstructed value lies within the range of
// the control points it reads — the culling metadata stays conservative once dilated to their footprint.
//
// Pieces: the cubic's break at integer u (cell [i, i+1) reads control points i-1 .. i+2), the
// quadratic's at half-integer u (cell [c - 1/2, c + 1/2) reads c-1 .. c+1). `BSplineBasis<D>` gives the
// D+1 basis polynomials of one piece in the local coordinate x in [0, 1); `bspline_sample` evaluates
// the filter from 8 trilinear fetches [SH05: Sigg & Hadwiger, GPU Gems 2 ch. 20]: per axis, neighbouring
// taps with weights a, b merge into one linear fetch at offset b / (a + b) — exact, since the weights are
// non-negative. Header-only, SL_HOST_DEVICE: the CUDA kernels run this code unchanged.
#pragma once

#include <cmath>

#include "core/util/config.h"
#include "core/util/math.h"
#include "core/scene/render_mode.h"

namespace sl {

// Polynomial degree of a filter's pieces per axis (1, 2, 3).
SL_HOST_DEVICE constexpr int filter_degree(Filter f) {
  return f == Filter::Cubic ? 3 : (f == Filter::Quadratic ? 2 : 1);
}

// The basis polynomials of one piece: B_m(x) = sum_j bspline_mono<D>(m, j) x^j, m = 0 .. D (the
// control point at offset m from the piece's first one). A function, not a table: the device reads it
// as constants once the loops over m and j are unrolled.
template <int D>
SL_HOST_DEVICE constexpr float bspline_mono(int m, int j) {
  if constexpr (D == 1) {
    return m == 0 ? (j == 0 ? 1.0f : -1.0f) : (j == 0 ? 0.0f : 1.0f);
  } else if constexpr (D == 2) {
    constexpr float c[3][3] = {{0.5f, -1.0f, 0.5f}, {0.5f, 1.0f, -1.0f}, {0.0f, 0.0f, 0.5f}};
    return c[m][j];
  } else {
    constexpr float c[4][4] = {{1.0f / 6.0f, -0.5f, 0.5f, -1.0f / 6.0f},
                               {2.0f / 3.0f, 0.0f, -1.0f, 0.5f},
                               {1.0f / 6.0f, 0.5f, 0.5f, -0.5f},
                               {0.0f, 0.0f, 0.0f, 1.0f / 6.0f}};
    return c[m][j];
  }
}

// Where the pieces of degree D lie: the walk coordinate u + bspline_grid_offset<D>() has the pieces at
// integers (cubic and linear: [i, i+1) of u; quadratic: [c - 1/2, c + 1/2)), and the piece's first
// control point is at offset bspline_first<D>() from the piece's index.
template <int D>
SL_HOST_DEVICE constexpr float bspline_grid_offset() { return D == 2 ? 0.5f : 0.0f; }
template <int D>
SL_HOST_DEVICE constexpr int bspline_first() { return D == 1 ? 0 : -1; }

// The D+1 basis values (w) and their derivatives with respect to x (dw) at x.
template <int D>
SL_HOST_DEVICE SL_INLINE void bspline_weights(float x, float w[D + 1], float dw[D + 1]) {
  for (int m = 0; m <= D; ++m) {
    float v = bspline_mono<D>(m, D), d = 0.0f;
    for (int j = D - 1; j >= 0; --j) {  // Horner, with the derivative alongside
      d = d * x + v;
      v = v * x + bspline_mono<D>(m, j);
    }
    w[m] = v;
    dw[m] = d;
  }
}

// One axis of the 8-fetch evaluation: the piece's two merged taps, as continuous voxel coordinates of
// the fetches (o0, o1) and their weights (g0, g1) at u.
SL_HOST_DEVICE SL_INLINE void bspline_taps(Filter f, float u, float& o0, float& o1, float& g0, float& g1) {
  if (f == Filter::Cubic) {
    const float i = floorf(u), x = u - i;
    const float x2 = x * x, x3 = x2 * x, r = 1.0f - x;
    const float w0 = r * r * r * (1.0f / 6.0f);
    const float w1 = (3.0f * x3 - 6.0f * x2 + 4.0f) * (1.0f / 6.0f);
    const float w2 = (-3.0f * x3 + 3.0f * x2 + 3.0f * x + 1.0f) * (1.0f / 6.0f);
    const float w3 = x3 * (1.0f / 6.0f);
    g0 = w0 + w1;  // >= 1/6 + 1/6 (both pairs): no division by zero
    g1 = w2 + w3;
    o0 = i - 1.0f + w1 / g0;
    o1 = i + 1.0f + w3 / g1;
  } else {  // quadratic: taps c-1, c merged, c+1 alone
    const float c = floorf(u + 0.5f), x = u + 0.5f - c;
    const float w0 = 0.5f * (1.0f - x) * (1.0f - x), w1 = 0.5f + x - x * x, w2 = 0.5f * x * x;
    g0 = w0 + w1;  // = 1 - x^2 / 2 >= 1/2
    g1 = w2;
    o0 = c - 1.0f + w1 / g0;
    o1 = c + 1.0f;
  }
}

// The B-spline value at world position p of a level with voxel size h, from 8 trilinear fetches
// `fetch(q)` at world positions q (the sampler's own trilinear sample, which clamps at the faces: the
// control points outside the volume repeat the edge voxels, as exact iso's do).
template <class Fetch>
SL_HOST_DEVICE SL_INLINE float bspline_sample(Filter f, const vec3& p, const vec3& h, const Fetch& fetch) {
  const vec3 u = p / h - 0.5f;
  float ox[2], oy[2], oz[2], gx[2], gy[2], gz[2];
  bspline_taps(f, u.x, ox[0], ox[1], gx[0], gx[1]);
  bspline_taps(f, u.y, oy[0], oy[1], gy[0], gy[1]);
  bspline_taps(f, u.z, oz[0], oz[1], gz[0], gz[1]);
  float v = 0.0f;
  SL_DEVICE_NO_UNROLL
  for (int n = 0; n < 8; ++n) {  // fetch n: x bit 0, y bit 1, z bit 2 (one call site for the device)
    const int i = n & 1, j = (n >> 1) & 1, k = n >> 2;
    v += (gx[i] * (gy[j] * gz[k])) * fetch(vec3((ox[i] + 0.5f) * h.x, (oy[j] + 0.5f) * h.y, (oz[k] + 0.5f) * h.z));
  }
  return v;
}

}  // namespace sl
