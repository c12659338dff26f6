// B-spline reconstruction (core/recon/bspline.h): the tri-quadratic and tri-cubic filters' ray
// polynomials in Bernstein form, their analytic gradients and the 8-fetch evaluation against the
// definition (RapidCheck), then exact-iso renders against closed forms (a plane: B-splines reproduce
// linear functions) and against a reference root found in double precision by a dense scan of the
// filter, the same roots for every skipping method, and the smoothing of a one-voxel sheet.
#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include <algorithm>
#include <cmath>

#include "core/scene/generate.h"
#include "core/recon/bspline.h"
#include "core/recon/exact_iso.h"
#include "core/frame/frame.h"
#include "core/frame/in_core_renderer.h"
#include "tests/core/recon/iso_fixtures.h"

namespace sl {
namespace {

using namespace iso_fixtures;

template <int D>
CellControl<D> random_control(float scale) {
  CellControl<D> c;
  for (float& v : c.v) v = *rc::gen::map(rc::gen::inRange(-1000, 1001), [&](int i) { return scale * float(i) / 1000.0f; });
  return c;
}

// The B-spline of a piece at local point f, in double, from the basis formulas (not bspline_mono).
template <int D>
double bspline_local_ref(const CellControl<D>& c, const glm::dvec3& f) {
  const auto w = [](double x, int m) {
    if constexpr (D == 2) {
      return m == 0 ? 0.5 * (1 - x) * (1 - x) : (m == 1 ? 0.5 + x - x * x : 0.5 * x * x);
    } else {
      const double r = 1 - x;
      return m == 0 ? r * r * r / 6 : m == 1 ? (3 * x * x * x - 6 * x * x + 4) / 6
                                     : m == 2 ? (-3 * x * x * x + 3 * x * x + 3 * x + 1) / 6 : x * x * x / 6;
    }
  };
  constexpr int n = D + 1;
  double r = 0.0;
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) r += double(c.v[i + n * (j + n * k)]) * w(f.x, i) * w(f.y, j) * w(f.z, k);
  return r;
}

template <int N>
double bernstein_eval(const float (&b)[N], double s) {
  double r = 0.0;
  for (int k = 0; k < N; ++k) {
    double bin = 1.0;
    for (int i = 1; i <= k; ++i) bin = bin * double(N - 1 - k + i) / i;
    r += double(b[k]) * bin * std::pow(s, k) * std::pow(1.0 - s, N - 1 - k);
  }
  return r;
}

template <int D>
void check_ray_bernstein() {
  const CellControl<D> c = random_control<D>(100.0f);
  const vec3 f0 = random_unit_point(), f1 = random_unit_point();
  float b[3 * D + 1];
  bspline_ray_bernstein<D>(c, f0, f1, b);
  for (double s : {0.0, 0.13, 0.5, 0.77, 1.0}) {
    const double expected = bspline_local_ref<D>(c, glm::dvec3(f0) + s * (glm::dvec3(f1) - glm::dvec3(f0)));
    RC_ASSERT(std::fabs(bernstein_eval(b, s) - expected) <= 1e-3);
    RC_ASSERT(std::fabs(double(bspline_local<D>(c, f0 + float(s) * (f1 - f0))) - expected) <= 1e-3);
  }
}

RC_GTEST_PROP(BSplineProperty, QuadraticRayPolynomialEqualsTheFilterAlongTheSegment, ()) { check_ray_bernstein<2>(); }
RC_GTEST_PROP(BSplineProperty, CubicRayPolynomialEqualsTheFilterAlongTheSegment, ()) { check_ray_bernstein<3>(); }

template <int D>
void check_gradient() {
  const CellControl<D> c = random_control<D>(100.0f);
  const vec3 f = vec3(0.05f) + 0.9f * random_unit_point();
  vec3 g;
  bspline_local<D>(c, f, &g);
  const double h = 1e-4;
  const glm::dvec3 fd0(f);
  const auto F = [&](const glm::dvec3& q) { return bspline_local_ref<D>(c, q); };
  const glm::dvec3 fd((F(fd0 + glm::dvec3(h, 0, 0)) - F(fd0 - glm::dvec3(h, 0, 0))) / (2 * h),
                      (F(fd0 + glm::dvec3(0, h, 0)) - F(fd0 - glm::dvec3(0, h, 0))) / (2 * h),
                      (F(fd0 + glm::dvec3(0, 0, h)) - F(fd0 - glm::dvec3(0, 0, h))) / (2 * h));
  const double scale = std::max(glm::length(fd), 1.0);
  RC_ASSERT(glm::length(glm::dvec3(g) - fd) <= 1e-3 * scale);
}

RC_GTEST_PROP(BSplineProperty, QuadraticAnalyticGradientEqualsFiniteDifferences, ()) { check_gradient<2>(); }
RC_GTEST_PROP(BSplineProperty, CubicAnalyticGradientEqualsFiniteDifferences, ()) { check_gradient<3>(); }

// The B-spline of a whole volume at world p (spacing 1) in double, control points clamped to the volume.
double bspline_ref(const Volume& v, Filter filter, const glm::dvec3& p) {
  const ivec3 d = v.dims();
  const glm::dvec3 u = p - 0.5;
  const int D = filter == Filter::Cubic ? 3 : 2;
  ivec3 first;
  glm::dvec3 x;
  for (int a = 0; a < 3; ++a) {
    const double piece = D == 3 ? std::floor(u[a]) : std::floor(u[a] + 0.5);
    x[a] = D == 3 ? u[a] - piece : u[a] + 0.5 - piece;
    first[a] = int(piece) - 1;
  }
  const auto w = [&](double t, int m) {
    if (D == 2) return m == 0 ? 0.5 * (1 - t) * (1 - t) : (m == 1 ? 0.5 + t - t * t : 0.5 * t * t);
    const double r = 1 - t;
    return m == 0 ? r * r * r / 6 : m == 1 ? (3 * t * t * t - 6 * t * t + 4) / 6
                                   : m == 2 ? (-3 * t * t * t + 3 * t * t + 3 * t + 1) / 6 : t * t * t / 6;
  };
  double r = 0.0;
  for (int k = 0; k <= D; ++k)
    for (int j = 0; j <= D; ++j)
      for (int i = 0; i <= D; ++i) {
        const ivec3 q = glm::clamp(first + ivec3(i, j, k), ivec3(0), d - 1);
        r += double(v.value(q.x, q.y, q.z)) * w(x.x, i) * w(x.y, j) * w(x.z, k);
      }
  return r;
}

// The 8-fetch evaluation [SH05] equals the B-spline's definition, interior and at the clamped faces.
RC_GTEST_PROP(BSplineProperty, EightTrilinearFetchesEqualTheFilter, ()) {
  const ivec3 dims(7, 6, 5);
  Volume v(VolumeDesc{dims, vec3(1.0f), VoxelType::F32});
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x) v.set(x, y, z, float(*rc::gen::inRange(0, 256)));
  const DenseGrid<float> grid{v.as<float>(), dims, vec3(1.0f)};
  const Filter filter = *rc::gen::element(Filter::Quadratic, Filter::Cubic);
  const vec3 p = random_unit_point() * vec3(dims);
  const float got = bspline_sample(filter, p, vec3(1.0f), [&](const vec3& q) { return grid.sample(q); });
  RC_ASSERT(std::fabs(double(got) - bspline_ref(v, filter, glm::dvec3(p))) <= 1e-3);
}

// The reference root of a B-spline, 1/500 voxel apart.
double bspline_reference_root(const Volume& v, Filter filter, const Ray& ray, double iso) {
  return first_crossing(v, ray, iso, 2e-3, [&](const glm::dvec3& p) { return bspline_ref(v, filter, p); });
}

// B-splines reproduce linear functions, so on a linear field (away from the clamped faces) the exact
// root is the plane's, for either filter.
TEST(ExactIsoBSpline, PlaneHitsWithinATenThousandthOfAVoxel) {
  const ivec3 dims(40, 36, 44);
  const Volume v = field(dims, [](double x, double y, double z) { return 2.0 * z + 0.3 * x - 0.2 * y; });
  const float iso = 40.0f;
  const glm::dvec3 g(0.3, -0.2, 2.0);
  for (const Filter filter : {Filter::Quadratic, Filter::Cubic}) {
    for (const vec3 dir : {vec3(0, 0, -1), vec3(0.3f, 0.2f, -1.0f)}) {
      const int size = 40;
      const Camera cam = ortho(0.5f * vec3(dims), dir, 30.0f, 80.0f);
      const RayGenerator gen = make_ray_generator(cam, size, size);
      const Frame f = render_iso(v, cam, iso, IsoMethod::Exact, size, 0.5f, SkipMethod::None, filter);
      const DepthErrors e = depth_errors(f, size, [&](int x, int y) {
        const Ray r = gen.ray(x, y);
        const double t = (iso - glm::dot(g, glm::dvec3(r.origin) - 0.5)) / glm::dot(g, glm::dvec3(r.dir));
        const glm::dvec3 u = glm::dvec3(r.origin) + t * glm::dvec3(r.dir) - 0.5;
        const bool inside = glm::all(glm::greaterThan(u, glm::dvec3(2.5))) &&
                            glm::all(glm::lessThan(u, glm::dvec3(dims) - 3.5));
        return inside ? t : NAN;
      });
      EXPECT_GT(e.checked, 400) << to_string(filter);
      EXPECT_EQ(e.missed, 0) << to_string(filter);
      EXPECT_LE(e.max, 1e-4) << to_string(filter) << " mean " << e.mean;
    }
  }
}

// On the sphere distance field of radius 8 the B-spline's own root (a dense scan of its definition in
// double) is found to 1e-3 voxel; the smoothing moves the surface off the analytic sphere by about
// the kernel's variance times the curvature (printed).
TEST(ExactIsoBSpline, SphereRootsMatchTheFiltersReferenceRoot) {
  const ivec3 small(24, 24, 24);
  const GeneratedVolume s = generate_volume("sphere", small, 1);
  const vec3 c = 0.5f * vec3(small);
  const int px = 24;
  const Camera cam = ortho(c, vec3(0.2f, 0.1f, -1.0f), 24.0f, 50.0f);
  const RayGenerator gen = make_ray_generator(cam, px, px);
  for (const Filter filter : {Filter::Quadratic, Filter::Cubic}) {
    const Frame exact = render_iso(s.intensity, cam, 8.0f, IsoMethod::Exact, px, 0.5f, SkipMethod::None, filter);
    const DepthErrors ref = depth_errors(exact, px, [&](int x, int y) {
      const double t = bspline_reference_root(s.intensity, filter, gen.ray(x, y), 8.0);
      return t >= 0.0 ? t : NAN;
    });
    const DepthErrors ana = depth_errors(exact, px, sphere_depth(gen, c, 8.0));
    EXPECT_GT(ref.checked, 60) << to_string(filter);
    EXPECT_EQ(ref.missed, 0) << to_string(filter);
    EXPECT_LE(ref.max, 1e-3) << to_string(filter) << " mean " << ref.mean;
    EXPECT_LE(ana.max, 0.25) << to_string(filter);
    std::printf("sphere R=8 %s: against its reference root max %.6f mean %.6f; against the sphere max %.4f mean %.4f\n",
                to_string(filter), ref.max, ref.mean, ana.max, ana.mean);
  }
}

TEST(ExactIsoBSpline, EveryMethodFindsTheSameRootsOnTheSphere) {
  const GeneratedVolume g = generate_volume("sphere", ivec3(61, 53, 47), 1);
  const Camera cam = default_camera(g.intensity.desc().extent());
  for (const Filter filter : {Filter::Quadratic, Filter::Cubic}) {
    const Frame ref = render_iso(g.intensity, cam, 15.0f, IsoMethod::Exact, 41, 0.5f, SkipMethod::None, filter);
    const auto& d0 = ref.image.channels.at("depth");
    int hits = 0;
    for (float d : d0) hits += d >= 0.0f;
    EXPECT_GT(hits, 80);
    for (SkipMethod m : {SkipMethod::BBox, SkipMethod::Octree, SkipMethod::SparseLeap}) {
      const Frame f = render_iso(g.intensity, cam, 15.0f, IsoMethod::Exact, 41, 0.5f, m, filter);
      EXPECT_EQ(f.image.channels.at("depth"), d0) << to_string(m) << " " << to_string(filter);
    }
  }
}

// The cubic B-spline smooths a one-voxel sheet: its peak is 2/3 of the plane's value, so an iso value
// above that finds nothing (the filter is approximating), one below it finds the smoothed sheet.
TEST(ExactIsoBSpline, CubicSmoothsAOneVoxelSheet) {
  const ivec3 dims(16, 16, 32);
  const Volume v = field(dims, [](double, double, double z) { return z == 29.0 ? 100.0 : 0.0; });
  const int size = 8;
  const Camera cam = ortho(0.5f * vec3(dims), vec3(0, 0, -1), 16.0f, 26.0f);
  const Frame above = render_iso(v, cam, 70.0f, IsoMethod::Exact, size, 0.5f, SkipMethod::None, Filter::Cubic);
  const Frame below = render_iso(v, cam, 60.0f, IsoMethod::Exact, size, 0.5f, SkipMethod::None, Filter::Cubic);
  for (int i = 0; i < size * size; ++i) {
    EXPECT_EQ(above.image.rgba[i].w, 0.0f);
    EXPECT_EQ(below.image.rgba[i].w, 1.0f);
    const RayGenerator gen = make_ray_generator(cam, size, size);
    const double t = bspline_reference_root(v, Filter::Cubic, gen.ray(i % size, i / size), 60.0);
    EXPECT_NEAR(below.image.channels.at("depth")[i], t, 1e-3);
  }
}

}  // namespace
}  // namespace sl
