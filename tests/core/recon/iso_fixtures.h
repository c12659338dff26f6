// Fixtures of the isosurface tests (exact_iso_test.cpp: trilinear; bspline_test.cpp: the B-splines):
// fields from closed forms, orthographic cameras, iso renders, the reference root (a dense
// double-precision scan of a filter along a ray) and the depth errors of a frame.
#pragma once

#include <rapidcheck.h>

#include <algorithm>
#include <cmath>
#include <functional>

#include "core/frame/frame.h"
#include "core/frame/in_core_renderer.h"
#include "core/util/ray.h"

namespace sl::iso_fixtures {

inline vec3 random_unit_point() {
  const auto u = [] { return float(*rc::gen::inRange(0, 1001)) / 1000.0f; };
  const float x = u(), y = u(), z = u();
  return vec3(x, y, z);
}

inline Camera ortho(const vec3& centre, const vec3& dir, float height, float distance) {
  Camera c;
  c.projection = Projection::Orthographic;
  c.center = centre;
  c.eye = centre - distance * glm::normalize(dir);
  c.up = std::fabs(dir.y) > 0.9f * glm::length(dir) ? vec3(1, 0, 0) : vec3(0, 1, 0);
  c.height = height;
  return c;
}

inline Volume field(const ivec3& dims, const std::function<double(double, double, double)>& f) {
  Volume v(VolumeDesc{dims, vec3(1.0f), VoxelType::F32});
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x) v.set(x, y, z, float(f(x, y, z)));
  return v;
}

// The reference root: the first sign change of F(p) - iso along the ray's stretch in the volume box, by
// a scan `h` voxel apart and bisection in double; -1 when none.
inline double first_crossing(const Volume& v, const Ray& ray, double iso, double h,
                             const std::function<double(const glm::dvec3&)>& F) {
  const Interval iv = intersect(ray, Box3{vec3(0.0f), v.desc().extent()});
  if (!(iv.t1 > iv.t0)) return -1.0;
  const glm::dvec3 o(ray.origin), d(ray.dir);
  const auto G = [&](double t) { return F(o + t * d) - iso; };
  const double t0 = std::max(0.0, double(iv.t0)), t1 = iv.t1;
  double prev = G(t0);
  for (double t = t0; t < t1; t += h) {
    double lo = t, hi = std::min(t + h, t1);
    const double gh = G(hi);
    if ((prev < 0.0) != (gh < 0.0)) {
      for (int k = 0; k < 50; ++k) {
        const double m = 0.5 * (lo + hi);
        ((G(m) < 0.0) == (G(lo) < 0.0) ? lo : hi) = m;
      }
      return 0.5 * (lo + hi);
    }
    prev = gh;
  }
  return -1.0;
}

inline Frame render_iso(const Volume& v, const Camera& cam, float iso, IsoMethod m, int size, float step = 0.5f,
                 SkipMethod method = SkipMethod::None, Filter filter = Filter::Linear) {
  const TransferFunction tf({{-1e6f, {1, 1, 1, 1}}, {1e6f, {1, 1, 1, 1}}});
  Scene scene{&v, nullptr, &tf, nullptr, cam};
  RenderSettings s;
  s.width = s.height = size;
  s.mode = RenderMode::Iso;
  s.iso = iso;
  s.iso_method = m;
  s.method = method;
  s.step = step;
  s.filter = filter;
  InCoreRenderer r;
  return r.render(scene, s);
}

// Errors of a frame's depth channel against `expected(x, y)` (NaN: pixel not checked).
struct DepthErrors {
  double max = 0.0, mean = 0.0;
  int checked = 0, missed = 0;
};
inline DepthErrors depth_errors(const Frame& f, int size, const std::function<double(int, int)>& expected) {
  DepthErrors e;
  const auto& depth = f.image.channels.at("depth");
  for (int y = 0; y < size; ++y) {
    for (int x = 0; x < size; ++x) {
      const double want = expected(x, y);
      if (std::isnan(want)) continue;
      const float got = depth[std::size_t(y) * size + x];
      if (got < 0.0f) {
        ++e.missed;
        continue;
      }
      const double err = std::fabs(double(got) - want);
      e.max = std::max(e.max, err);
      e.mean += err;
      ++e.checked;
    }
  }
  if (e.checked) e.mean /= e.checked;
  return e;
}

// A sphere distance field; for each pixel the analytic sphere's depth where the ray meets it steeply
// (|sin| <= 0.6 against the normal), else NaN.
inline std::function<double(int, int)> sphere_depth(const RayGenerator& gen, const vec3& centre, double radius) {
  return [=](int x, int y) {
    const Ray r = gen.ray(x, y);
    const glm::dvec3 oc = glm::dvec3(r.origin) - glm::dvec3(centre), d(r.dir);
    const double bb = glm::dot(oc, d), cc = glm::dot(oc, oc) - radius * radius;
    const double disc = bb * bb - cc;
    if (disc < 0.0) return double(NAN);
    const double perp2 = glm::dot(oc, oc) - bb * bb;
    if (perp2 > 0.36 * radius * radius) return double(NAN);
    return -bb - std::sqrt(disc);
  };
}

}  // namespace sl::iso_fixtures
