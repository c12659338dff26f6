// Exact isosurfaces (DESIGN.md "Ray casting"; seed 004, Steinberger, "Highly accurate multiresolution isosurface
// rendering", ch. 3): per cell of the voxel-centre grid the trilinear interpolant restricted to the ray is a
// cubic in t; written in Bernstein form on the ray's stretch inside the cell, its first root is found by
// LR81 (Lane & Riesenfeld 1981: De Casteljau subdivision guided by the control polygon, discarding pieces
// whose control points keep one sign — the variation-diminishing property), and the normal is the
// interpolant's analytic gradient at the hit. The tri-quadratic and tri-cubic B-splines (core/recon/bspline.h)
// take the same path with ray polynomials of degree 6 and 9 (CellControl, bspline_ray_bernstein).
// Header-only, SL_HOST_DEVICE, no containers: the CUDA kernels run this code unchanged.
#pragma once

#include <cmath>
#include <cstdint>

#include "core/recon/bspline.h"
#include "core/util/config.h"
#include "core/util/math.h"
#include "core/util/ray.h"

namespace sl {

// The 8 values of one cell of the voxel-centre grid, minus the iso value; index bit 0 is +x, bit 1 +y,
// bit 2 +z. Subtracting the iso value first keeps the polynomial's coefficients small near a root
// (the trilinear weights sum to one, so F - iso interpolates the shifted values).
struct CellCorners {
  float v[8];

  SL_HOST_DEVICE SL_INLINE bool may_cross() const {
    // Some corner below zero and some not: only then can the interpolant (a convex combination of
    // the corners) change sign inside the cell (the cell's min/max test).
    bool below = false, above = false;
    for (int i = 0; i < 8; ++i) (v[i] < 0.0f ? below : above) = true;
    return below && above;
  }
};

// The interpolant at local coordinates f in [0,1]^3 of the cell.
SL_HOST_DEVICE inline float trilinear_local(const CellCorners& c, const vec3& f) {
  const float x00 = c.v[0] + f.x * (c.v[1] - c.v[0]), x10 = c.v[2] + f.x * (c.v[3] - c.v[2]);
  const float x01 = c.v[4] + f.x * (c.v[5] - c.v[4]), x11 = c.v[6] + f.x * (c.v[7] - c.v[6]);
  const float y0 = x00 + f.y * (x10 - x00), y1 = x01 + f.y * (x11 - x01);
  return y0 + f.z * (y1 - y0);
}

// Its analytic gradient with respect to f (multiply by 1 / voxel size for world units).
SL_HOST_DEVICE inline vec3 trilinear_gradient_local(const CellCorners& c, const vec3& f) {
  const float gx = 1.0f - f.x, gy = 1.0f - f.y, gz = 1.0f - f.z;
  const float dx = gy * gz * (c.v[1] - c.v[0]) + f.y * gz * (c.v[3] - c.v[2]) + gy * f.z * (c.v[5] - c.v[4]) +
                   f.y * f.z * (c.v[7] - c.v[6]);
  const float dy = gx * gz * (c.v[2] - c.v[0]) + f.x * gz * (c.v[3] - c.v[1]) + gx * f.z * (c.v[6] - c.v[4]) +
                   f.x * f.z * (c.v[7] - c.v[5]);
  const float dz = gx * gy * (c.v[4] - c.v[0]) + f.x * gy * (c.v[5] - c.v[1]) + gx * f.y * (c.v[6] - c.v[2]) +
                   f.x * f.y * (c.v[7] - c.v[3]);
  return vec3(dx, dy, dz);
}

// Bernstein coefficients on s in [0,1] of the interpolant along the straight segment from local point f0
// (s = 0) to f1 (s = 1). Each trilinear weight is a product of three functions linear in s; a product
// l·m·n of linear functions with end values (l0, l1), ... has the cubic Bernstein coefficients
// l0m0n0, (l1m0n0 + l0m1n0 + l0m0n1)/3, (l0m1n1 + l1m0n1 + l1m1n0)/3, l1m1n1.
SL_HOST_DEVICE inline void ray_bernstein(const CellCorners& c, const vec3& f0, const vec3& f1, float b[4]) {
  b[0] = b[1] = b[2] = b[3] = 0.0f;
  for (int i = 0; i < 8; ++i) {
    const float x0 = (i & 1) ? f0.x : 1.0f - f0.x, x1 = (i & 1) ? f1.x : 1.0f - f1.x;
    const float y0 = (i & 2) ? f0.y : 1.0f - f0.y, y1 = (i & 2) ? f1.y : 1.0f - f1.y;
    const float z0 = (i & 4) ? f0.z : 1.0f - f0.z, z1 = (i & 4) ? f1.z : 1.0f - f1.z;
    const float v = c.v[i];
    b[0] += v * (x0 * y0 * z0);
    b[1] += v * ((x1 * y0 * z0 + x0 * y1 * z0 + x0 * y0 * z1) * (1.0f / 3.0f));
    b[2] += v * ((x0 * y1 * z1 + x1 * y0 * z1 + x1 * y1 * z0) * (1.0f / 3.0f));
    b[3] += v * (x1 * y1 * z1);
  }
}

// The control points of one piece of a B-spline of degree D (core/recon/bspline.h) minus the iso value: the
// (D+1)^3 voxels from the piece's first control point, index x + (D+1) (y + (D+1) z).
template <int D>
struct CellControl {
  static constexpr int kN = D + 1;
  static constexpr int kCount = kN * kN * kN;
  float v[kCount];

  // The cell's min/max test: the B-spline is a convex combination of these (non-negative weights
  // summing to one), so it can reach zero only if some control point is below and some is not.
  SL_HOST_DEVICE SL_INLINE bool may_cross() const {
    bool below = false, above = false;
    for (int i = 0; i < kCount; ++i) (v[i] < 0.0f ? below : above) = true;
    return below && above;
  }
};

// n choose k, as a float (small n).
SL_HOST_DEVICE constexpr float binomial(int n, int k) {
  float r = 1.0f;
  for (int i = 1; i <= k; ++i) r = r * float(n - k + i) / float(i);
  return r;
}

// The scaled Bernstein coefficients (degree D, coefficient k times C(D, k)) on s in [0,1] of the basis
// polynomials B_m(x(s)), x(s) = x0 + s (x1 - x0). Coefficient k of a polynomial is its blossom at
// (x0 repeated D-k times, x1 k times); the blossom of x^j is the elementary symmetric polynomial of
// degree j of those arguments over C(D, j).
template <int D>
SL_HOST_DEVICE SL_INLINE void bspline_axis_bernstein(float x0, float x1, float out[D + 1][D + 1]) {
  float p0[D + 1], p1[D + 1];
  p0[0] = p1[0] = 1.0f;
  for (int j = 1; j <= D; ++j) {
    p0[j] = p0[j - 1] * x0;
    p1[j] = p1[j - 1] * x1;
  }
  for (int k = 0; k <= D; ++k) {
    float blossom[D + 1];  // of x^j, j = 0 .. D
    for (int j = 0; j <= D; ++j) {
      float e = 0.0f;
      for (int m = 0; m <= j; ++m) {
        if (m > k || j - m > D - k) continue;
        e += binomial(k, m) * binomial(D - k, j - m) * p1[m] * p0[j - m];
      }
      blossom[j] = e / binomial(D, j);
    }
    for (int m = 0; m <= D; ++m) {
      float c = 0.0f;
      for (int j = 0; j <= D; ++j) c += bspline_mono<D>(m, j) * blossom[j];
      out[m][k] = c * binomial(D, k);
    }
  }
}

// The Bernstein coefficients (degree 3D) on s in [0,1] of the B-spline of piece `c` along the straight
// segment from local point f0 (s = 0) to f1 (s = 1): the tensor product of the three axes' basis
// polynomials, multiplied in the scaled Bernstein form (a product is a convolution there).
template <int D>
SL_HOST_DEVICE inline void bspline_ray_bernstein(const CellControl<D>& c, const vec3& f0, const vec3& f1,
                                                 float b[3 * D + 1]) {
  constexpr int n = D + 1;
  float X[n][n], Y[n][n], Z[n][n];
  bspline_axis_bernstein<D>(f0.x, f1.x, X);
  bspline_axis_bernstein<D>(f0.y, f1.y, Y);
  bspline_axis_bernstein<D>(f0.z, f1.z, Z);
  float F[3 * D + 1];
  for (int q = 0; q <= 3 * D; ++q) F[q] = 0.0f;
  for (int k = 0; k < n; ++k) {
    float B[2 * D + 1];
    for (int q = 0; q <= 2 * D; ++q) B[q] = 0.0f;
    for (int j = 0; j < n; ++j) {
      float A[n];
      for (int q = 0; q < n; ++q) A[q] = 0.0f;
      for (int i = 0; i < n; ++i) {
        const float v = c.v[i + n * (j + n * k)];
        for (int q = 0; q < n; ++q) A[q] += v * X[i][q];
      }
      for (int q = 0; q < n; ++q) {
        for (int r = 0; r < n; ++r) B[q + r] += A[q] * Y[j][r];
      }
    }
    for (int q = 0; q <= 2 * D; ++q) {
      for (int r = 0; r < n; ++r) F[q + r] += B[q] * Z[k][r];
    }
  }
  for (int q = 0; q <= 3 * D; ++q) b[q] = F[q] / binomial(3 * D, q);
}

// The B-spline of piece `c` at local coordinates f in [0,1]^3, and its analytic gradient with respect
// to f (multiply by 1 / voxel size for world units).
template <int D>
SL_HOST_DEVICE inline float bspline_local(const CellControl<D>& c, const vec3& f, vec3* gradient = nullptr) {
  constexpr int n = D + 1;
  float wx[n], wy[n], wz[n], dx[n], dy[n], dz[n];
  bspline_weights<D>(f.x, wx, dx);
  bspline_weights<D>(f.y, wy, dy);
  bspline_weights<D>(f.z, wz, dz);
  float v = 0.0f;
  vec3 g(0.0f);
  for (int k = 0; k < n; ++k) {
    for (int j = 0; j < n; ++j) {
      for (int i = 0; i < n; ++i) {
        const float cv = c.v[i + n * (j + n * k)];
        v += cv * (wx[i] * wy[j] * wz[k]);
        g.x += cv * (dx[i] * wy[j] * wz[k]);
        g.y += cv * (wx[i] * dy[j] * wz[k]);
        g.z += cv * (wx[i] * wy[j] * dz[k]);
      }
    }
  }
  if (gradient) *gradient = g;
  return v;
}

namespace bernstein {

// The control polygon changes sign (sign: below zero or not, as the sampled method brackets crossings).
template <int N>
SL_HOST_DEVICE SL_INLINE bool sign_change(const float (&b)[N]) {
  const bool s = b[0] < 0.0f;
  for (int i = 1; i < N; ++i) {
    if ((b[i] < 0.0f) != s) return true;
  }
  return false;
}

// De Casteljau subdivision at x in (0,1): `left` on [0,x], `right` on [x,1], each rescaled to [0,1].
template <int N>
SL_HOST_DEVICE SL_INLINE void split(const float (&b)[N], float x, float (&left)[N], float (&right)[N]) {
  float a[N];
  for (int i = 0; i < N; ++i) a[i] = b[i];
  left[0] = a[0];
  right[N - 1] = a[N - 1];
  for (int r = 1; r < N; ++r) {
    for (int i = 0; i + r < N; ++i) a[i] = a[i] + x * (a[i + 1] - a[i]);
    left[r] = a[0];
    right[N - 1 - r] = a[N - 1 - r];
  }
}

// The coefficients on [lo, 1] of the polynomial p on [0,1].
template <int N>
SL_HOST_DEVICE SL_INLINE void tail(const float (&p)[N], float lo, float (&out)[N]) {
  if (!(lo > 0.0f)) {
    for (int i = 0; i < N; ++i) out[i] = p[i];
    return;
  }
  float left[N];
  split(p, lo, left, out);
}

// Where the control polygon (control point i at i/(N-1)) first crosses zero; 0.5 if it does not.
template <int N>
SL_HOST_DEVICE SL_INLINE float polygon_crossing(const float (&b)[N]) {
  for (int i = 0; i < N - 1; ++i) {
    if ((b[i] < 0.0f) != (b[i + 1] < 0.0f)) {
      const float d = b[i] - b[i + 1];
      const float f = d != 0.0f ? b[i] / d : 0.5f;
      return (float(i) + (f > 0.0f ? (f < 1.0f ? f : 1.0f) : 0.0f)) * (1.0f / float(N - 1));
    }
  }
  return 0.5f;
}

}  // namespace bernstein

// LR81: the first root in [s_from, 1] of the polynomial with Bernstein coefficients p on [0,1] (degree
// N-1: 3 for the trilinear interpolant, 6 and 9 for the B-splines), to within `tol` (in s). Subdivides
// at the control polygon's first crossing (kept away from the ends, so every step shrinks the piece by
// at least a fifth) and keeps the left piece while its control points change sign; a piece whose
// control points keep one sign holds no root and is discarded. No stack: everything before `lo` is
// known root-free, so after a dud (a sign change of the polygon but none of the curve) the search
// resumes on [hi, 1], recomputed from p. False: no root in [s_from, 1].
template <int N>
SL_HOST_DEVICE inline bool lr81_first_root(const float (&p)[N], float s_from, float tol, float& root) {
  float lo = s_from > 0.0f ? s_from : 0.0f;
  for (int restart = 0; restart < 32 && lo < 1.0f; ++restart) {
    float c[N];
    bernstein::tail(p, lo, c);
    if (!bernstein::sign_change(c)) return false;
    float hi = 1.0f;
    bool dud = false;
    for (int it = 0; it < 96; ++it) {
      const float w = hi - lo;
      if (w <= tol) break;
      float x = bernstein::polygon_crossing(c);
      x = x < 0.2f ? 0.2f : (x > 0.8f ? 0.8f : x);
      float left[N], right[N];
      bernstein::split(c, x, left, right);
      const float m = lo + x * w;
      if (bernstein::sign_change(left)) {
        hi = m;
        for (int i = 0; i < N; ++i) c[i] = left[i];
      } else if (bernstein::sign_change(right)) {
        lo = m;
        for (int i = 0; i < N; ++i) c[i] = right[i];
      } else {
        dud = true;  // [lo, hi] holds no root
        break;
      }
    }
    if (!dud) {
      root = lo + bernstein::polygon_crossing(c) * (hi - lo);
      return true;
    }
    lo = hi;
  }
  return false;
}

// The cells of the voxel-centre grid of one level that a ray crosses, in order (a 3-D DDA). Cell c spans
// continuous voxel coordinates [c, c+1] per axis, u = world / voxel size - 0.5 (voxel centres at
// integers, DESIGN.md "Ray casting"); cells -1 and dims-1 hold the half voxel at the volume's faces, where the
// clamped interpolant is the cell's with repeated corners. A cell's stretch [t0, t1] of the ray is its
// slab intersection, computed from the cell alone, so the root found in a cell does not depend on where
// a skipping method's span started the walk (every method gives the same image).
struct CellWalk {
  vec3 uo{0.0f}, ud{0.0f};  // u(t) = uo + t * ud
  ivec3 cell{0};
  float t0 = 0.0f, t1 = 0.0f;  // the current cell's stretch of the ray
  int axis = 0;                // the axis through whose face the ray leaves the cell
  int step = 0;                // and the direction (+1 / -1)

  // `grid_offset`: the pieces of the filter lie at integers of u + grid_offset (bspline_grid_offset:
  // 0 for the trilinear and tri-cubic pieces, 1/2 for the tri-quadratic ones).
  SL_HOST_DEVICE CellWalk(const Ray& ray, const vec3& inv_voxel, float t, float grid_offset = 0.0f) {
    uo = ray.origin * inv_voxel - (0.5f - grid_offset);
    ud = ray.dir * inv_voxel;
    const vec3 u = uo + t * ud;
    cell = ivec3(int(floorf(u.x)), int(floorf(u.y)), int(floorf(u.z)));
    bounds();
  }

  // The local coordinates (in [0,1]^3) of the ray's point at t in the current cell.
  SL_HOST_DEVICE SL_INLINE vec3 local(float t) const {
    return glm::clamp(uo + t * ud - vec3(cell), vec3(0.0f), vec3(1.0f));
  }

  SL_HOST_DEVICE SL_INLINE void advance() {
    cell[axis] += step;
    bounds();
  }

 private:
  SL_HOST_DEVICE void bounds() {
    t0 = -INFINITY;
    t1 = INFINITY;
    axis = 0;
    step = 1;
    for (int a = 0; a < 3; ++a) {
      if (ud[a] == 0.0f) continue;  // parallel to the slab: inside it for the whole ray
      const float inv = 1.0f / ud[a];
      const float ta = (float(cell[a]) - uo[a]) * inv, tb = (float(cell[a] + 1) - uo[a]) * inv;
      const float lo = ud[a] > 0.0f ? ta : tb, hi = ud[a] > 0.0f ? tb : ta;
      if (lo > t0) t0 = lo;
      if (hi < t1) {
        t1 = hi;
        axis = a;
        step = ud[a] > 0.0f ? 1 : -1;
      }
    }
  }
};

}  // namespace sl
