#include "core/lists/screen_rays.h"

#include <algorithm>
#include <cmath>

#include <glm/gtc/type_precision.hpp>

#if defined(__SSE2__) && !defined(SL_NO_SSE)
#include <emmintrin.h>
#define SL_SSE_RAYS 1
#else
#define SL_SSE_RAYS 0
#endif

namespace sl {

ScreenRect conservative_screen_rect(const Box3& box, const RayGenerator& gen) {
  // A corner relative to the eye takes, per axis, the box's low or high side: its component along a
  // camera axis is the sum of three per-axis products, each made once for both sides.
  const double eye[3] = {gen.eye.x, gen.eye.y, gen.eye.z};
  const double fw[3] = {gen.forward.x, gen.forward.y, gen.forward.z}, rt[3] = {gen.right.x, gen.right.y, gen.right.z},
               up[3] = {gen.up.x, gen.up.y, gen.up.z};
  double cz[3][2], cx[3][2], cy[3][2];  // [axis][low, high side]
  double zmin = 0.0, zmax = 0.0, d2max = 0.0;
  for (int a = 0; a < 3; ++a) {
    const double d[2] = {double(box.lo[a]) - eye[a], double(box.hi[a]) - eye[a]};
    for (int h = 0; h < 2; ++h) {
      cz[a][h] = d[h] * fw[a];
      cx[a][h] = d[h] * rt[a];
      cy[a][h] = d[h] * up[a];
    }
    zmin += std::min(cz[a][0], cz[a][1]);  // the corners' extremes are sums of the axes' extremes
    zmax += std::max(cz[a][0], cz[a][1]);
    d2max += std::max(d[0] * d[0], d[1] * d[1]);
  }
  // Rays move forward (perspective: every direction has a positive forward component; orthographic:
  // origins on the eye plane), so a box wholly behind the eye plane is met only at t <= 0. The
  // tolerance keeps boxes touching the plane, where float slab tests may still report t1 > 0.
  const double tol = 1e-5 * std::sqrt(d2max) + 1e-30;
  if (zmax < -tol) return ScreenRect{};
  const ScreenRect full{0, 0, gen.width - 1, gen.height - 1};
  if (!gen.orthographic && zmin <= tol) return full;  // holds the eye or straddles the eye plane
  double xmin = HUGE_VAL, xmax = -HUGE_VAL, ymin = HUGE_VAL, ymax = -HUGE_VAL;
  if (gen.orthographic) {
    xmin = ymin = xmax = ymax = 0.0;
    for (int a = 0; a < 3; ++a) {
      xmin += std::min(cx[a][0], cx[a][1]);
      xmax += std::max(cx[a][0], cx[a][1]);
      ymin += std::min(cy[a][0], cy[a][1]);
      ymax += std::max(cy[a][0], cy[a][1]);
    }
  } else {
    for (int k = 0; k < 8; ++k) {
      const int hx = k & 1, hy = (k >> 1) & 1, hz = (k >> 2) & 1;
      const double iz = 1.0 / ((cz[0][hx] + cz[1][hy]) + cz[2][hz]);
      const double x = ((cx[0][hx] + cx[1][hy]) + cx[2][hz]) * iz, y = ((cy[0][hx] + cy[1][hy]) + cy[2][hz]) * iz;
      xmin = std::min(xmin, x);
      xmax = std::max(xmax, x);
      ymin = std::min(ymin, y);
      ymax = std::max(ymax, y);
    }
  }
  // Inverse of RayGenerator::ray: screen coordinate -> continuous pixel index of the pixel centre.
  const double half_h = gen.half_h, half_w = double(gen.half_h) * double(gen.aspect);
  auto px = [&](double sx) { return (sx / half_w + 1.0) * 0.5 * gen.width - 0.5; };
  auto py = [&](double sy) { return (1.0 - sy / half_h) * 0.5 * gen.height - 0.5; };
  // A pixel's ray hits the box only if its centre (continuous index: the pixel's own) projects into
  // the corners' bounds, so the rectangle is the pixels whose centres lie in them, give or take kTol:
  // the float ray generation and slab test err by about 1e-4 pixel at 4096 pixels a side.
  constexpr double kTol = 0.01;
  const double fx0 = std::ceil(px(xmin) - kTol), fx1 = std::floor(px(xmax) + kTol);
  const double fy0 = std::ceil(py(ymax) - kTol), fy1 = std::floor(py(ymin) + kTol);
  if (fx0 > fx1 || fy0 > fy1) return ScreenRect{};  // between pixel centres
  if (fx1 < 0.0 || fy1 < 0.0 || fx0 > gen.width - 1 || fy0 > gen.height - 1) return ScreenRect{};
  ScreenRect r;
  r.x0 = int(std::max(fx0, 0.0));
  r.y0 = int(std::max(fy0, 0.0));
  r.x1 = int(std::min(fx1, double(gen.width - 1)));
  r.y1 = int(std::min(fy1, double(gen.height - 1)));
  return r;
}

namespace detail {

// gen.ray(x, y) written out per component (the same IEEE operations in the same order: glm's
// normalize is v * (1 / sqrt(dot(v, v))), its dot (x*x + y*y) + z*z), with the screen coordinates
// made once per column and row rather than once per pixel. With SSE2,
// perspective rays four pixels at a time: the same operations per lane (sqrtps and divps round as
// sqrtss and divss; no contraction into FMA), slab_reciprocal's +inf for either zero made by a blend.
void tile_rays(const RayGenerator& gen, const ScreenRect& tile, float (*origin)[kTileSize * kTileSize],
               float (*inv_dir)[kTileSize * kTileSize], float (*dir)[kTileSize * kTileSize]) {
  constexpr int T = kTileSize;
  alignas(16) float sx[T];
  float sy[T];
  for (int l = 0; l < T; ++l) {
    sx[l] = (2.0f * (float(tile.x0 + l) + 0.5f) / float(gen.width) - 1.0f) * gen.half_h * gen.aspect;
    sy[l] = (1.0f - 2.0f * (float(tile.y0 + l) + 0.5f) / float(gen.height)) * gen.half_h;
  }
  const float fx = gen.forward.x, fy = gen.forward.y, fz = gen.forward.z;
  const float rx = gen.right.x, ry = gen.right.y, rz = gen.right.z;
  const float ux = gen.up.x, uy = gen.up.y, uz = gen.up.z;
  const float ex = gen.eye.x, ey = gen.eye.y, ez = gen.eye.z;
  const int inside_x = tile.x1 - tile.x0 + 1;  // pixels of a row within the image
  for (int ly = 0; ly < T; ++ly) {
    const float v = sy[ly];
    int lx = 0;
#if SL_SSE_RAYS
    if (!gen.orthographic && tile.y0 + ly <= tile.y1) {
      const __m128 one = _mm_set1_ps(1.0f), zero = _mm_setzero_ps(), inf = _mm_set1_ps(__builtin_huge_valf());
      const __m128 vx = _mm_set1_ps(v * ux), vy = _mm_set1_ps(v * uy), vz = _mm_set1_ps(v * uz);
      for (; lx + 4 <= inside_x; lx += 4) {
        const int k = ly * T + lx;
        const __m128 u = _mm_load_ps(sx + lx);
        const __m128 dx = _mm_add_ps(_mm_add_ps(_mm_set1_ps(fx), _mm_mul_ps(u, _mm_set1_ps(rx))), vx);
        const __m128 dy = _mm_add_ps(_mm_add_ps(_mm_set1_ps(fy), _mm_mul_ps(u, _mm_set1_ps(ry))), vy);
        const __m128 dz = _mm_add_ps(_mm_add_ps(_mm_set1_ps(fz), _mm_mul_ps(u, _mm_set1_ps(rz))), vz);
        const __m128 len2 = _mm_add_ps(_mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy)), _mm_mul_ps(dz, dz));
        const __m128 n = _mm_div_ps(one, _mm_sqrt_ps(len2));
        const __m128 d[3] = {_mm_mul_ps(dx, n), _mm_mul_ps(dy, n), _mm_mul_ps(dz, n)};
        const float e[3] = {ex, ey, ez};
        for (int a = 0; a < 3; ++a) {
          const __m128 z = _mm_cmpeq_ps(d[a], zero);
          const __m128 r = _mm_or_ps(_mm_and_ps(z, inf), _mm_andnot_ps(z, _mm_div_ps(one, d[a])));
          _mm_storeu_ps(inv_dir[a] + k, r);
          _mm_storeu_ps(origin[a] + k, _mm_set1_ps(e[a]));
          if (dir) _mm_storeu_ps(dir[a] + k, d[a]);
        }
      }
    }
#endif
    for (; lx < T; ++lx) {
      const int k = ly * T + lx;
      if (tile.x0 + lx > tile.x1 || tile.y0 + ly > tile.y1) {  // past the image edge: zero, never used
        for (int a = 0; a < 3; ++a) origin[a][k] = inv_dir[a][k] = 0.0f;
        if (dir) dir[0][k] = dir[1][k] = dir[2][k] = 0.0f;
        continue;
      }
      const float u = sx[lx];
      if (gen.orthographic) {
        origin[0][k] = (ex + u * rx) + v * ux;
        origin[1][k] = (ey + u * ry) + v * uy;
        origin[2][k] = (ez + u * rz) + v * uz;
        inv_dir[0][k] = slab_reciprocal(fx);
        inv_dir[1][k] = slab_reciprocal(fy);
        inv_dir[2][k] = slab_reciprocal(fz);
        if (dir) {
          dir[0][k] = fx;
          dir[1][k] = fy;
          dir[2][k] = fz;
        }
      } else {
        const float dx = (fx + u * rx) + v * ux, dy = (fy + u * ry) + v * uy, dz = (fz + u * rz) + v * uz;
        const float n = 1.0f / std::sqrt((dx * dx + dy * dy) + dz * dz);
        origin[0][k] = ex;
        origin[1][k] = ey;
        origin[2][k] = ez;
        inv_dir[0][k] = slab_reciprocal(dx * n);
        inv_dir[1][k] = slab_reciprocal(dy * n);
        inv_dir[2][k] = slab_reciprocal(dz * n);
        if (dir) {
          dir[0][k] = dx * n;
          dir[1][k] = dy * n;
          dir[2][k] = dz * n;
        }
      }
    }
  }
}

}  // namespace detail

}  // namespace sl
