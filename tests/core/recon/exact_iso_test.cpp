// Exact isosurfaces (core/recon/exact_iso.h, seed 004): the ray polynomial in Bernstein form, LR81's first
// root, the cell walk and the analytic gradient, then whole renders against closed forms (a plane, a
// product of linear factors, a sphere distance field) and against a reference root found in double
// precision by a dense scan of the same clamped trilinear interpolant.
#include <cfloat>
#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <set>

#include "core/scene/generate.h"
#include "core/cast/cast_pixel.h"
#include "core/recon/exact_iso.h"
#include "core/frame/frame.h"
#include "core/frame/in_core_renderer.h"
#include "tests/core/recon/iso_fixtures.h"

namespace sl {
namespace {

using namespace iso_fixtures;

// Bernstein evaluation by De Casteljau (the split point's value).
float bernstein_at(const float (&b)[4], float s) {
  float l[4], r[4];
  bernstein::split(b, s, l, r);
  return l[3];
}

CellCorners random_corners(float scale) {
  CellCorners c;
  for (float& v : c.v) v = *rc::gen::map(rc::gen::inRange(-1000, 1001), [&](int i) { return scale * float(i) / 1000.0f; });
  return c;
}

RC_GTEST_PROP(ExactIsoProperty, BernsteinFormEqualsTheInterpolantAlongTheSegment, ()) {
  const CellCorners c = random_corners(100.0f);
  const vec3 f0 = random_unit_point(), f1 = random_unit_point();
  float b[4];
  ray_bernstein(c, f0, f1, b);
  for (float s : {0.0f, 0.17f, 0.5f, 0.83f, 1.0f}) {
    const float expected = trilinear_local(c, f0 + s * (f1 - f0));
    RC_ASSERT(std::fabs(bernstein_at(b, s) - expected) <= 1e-3f);
  }
}

// (x - a)(y - b)(z - c) on a cell is trilinear, so it is its own interpolant; along a segment it is a cubic
// whose roots are where each factor vanishes.
RC_GTEST_PROP(ExactIsoProperty, Lr81FindsTheFirstRootOfAProductOfLinearFactors, ()) {
  const vec3 abc = random_unit_point();
  CellCorners c;
  for (int i = 0; i < 8; ++i) {
    c.v[i] = (float(i & 1) - abc.x) * (float((i >> 1) & 1) - abc.y) * (float((i >> 2) & 1) - abc.z);
  }
  const vec3 f0 = random_unit_point(), f1 = random_unit_point();
  const float len = glm::length(f1 - f0);
  RC_PRE(len > 1e-2f);
  // The factor roots in (0, 1), the first of which changes the sign (distinct: a double root does not).
  double roots[3];
  int n = 0;
  for (int a = 0; a < 3; ++a) {
    // No factor (nearly) zero along the whole segment: the product would vanish identically.
    RC_PRE(std::max(std::fabs(f0[a] - abc[a]), std::fabs(f1[a] - abc[a])) > 1e-2f);
    const double d = double(f1[a]) - double(f0[a]);
    if (d == 0.0) continue;
    const double s = (double(abc[a]) - double(f0[a])) / d;
    RC_PRE(std::fabs(s) > 1e-3 && std::fabs(s - 1.0) > 1e-3);  // not at an end of the segment
    if (s > 0.0 && s < 1.0) {
      // Insertion into the sorted roots.
      int j = n++;
      for (; j > 0 && roots[j - 1] > s; --j) roots[j] = roots[j - 1];
      roots[j] = s;
    }
  }
  for (int i = 0; i + 1 < n; ++i) RC_PRE(roots[i + 1] - roots[i] > 1e-3);  // no (near-)double roots
  // Roots float arithmetic can place within the tolerance: moving by it changes the cubic by more than
  // a few roundings of the corner values (two roots 1e-2 apart on a segment whose three factors change
  // slowly leave a slope of 5e-6 there, and a root float cannot find to 1e-4).
  float vmax = 0.0f;
  for (float v : c.v) vmax = std::max(vmax, std::fabs(v));
  const auto slope = [&](double t) {
    double sum = 0.0;
    for (int a = 0; a < 3; ++a) {
      double term = double(f1[a]) - double(f0[a]);
      for (int k = 0; k < 3; ++k) {
        if (k != a) term *= double(f0[k]) + t * (double(f1[k]) - double(f0[k])) - double(abc[k]);
      }
      sum += term;
    }
    return std::fabs(sum);
  };
  for (int i = 0; i < std::min(n, 2); ++i) {
    RC_PRE(slope(roots[i]) * (1e-4 / double(len)) > 4.0 * double(FLT_EPSILON) * double(vmax));
  }
  float b[4];
  ray_bernstein(c, f0, f1, b);
  float s = -1.0f;
  const bool found = lr81_first_root(b, 0.0f, 1e-6f / len, s);
  RC_ASSERT(found == (n > 0));
  if (n > 0) RC_ASSERT(std::fabs(double(s) - roots[0]) * double(len) <= 1e-4);
  // The search from just past the first root finds the second.
  if (n > 1) {
    RC_ASSERT(lr81_first_root(b, float(roots[0] + 5e-4), 1e-6f / len, s));
    RC_ASSERT(std::fabs(double(s) - roots[1]) * double(len) <= 1e-4);
  }
}

// Any cubic given by random corners: LR81's first root against a dense scan in double precision.
RC_GTEST_PROP(ExactIsoProperty, Lr81MatchesADenseScan, ()) {
  const CellCorners c = random_corners(1.0f);
  const vec3 f0 = random_unit_point(), f1 = random_unit_point();
  float b[4];
  ray_bernstein(c, f0, f1, b);
  const auto F = [&](double s) {
    const double p[4] = {b[0], b[1], b[2], b[3]};
    const double u = 1.0 - s;
    return u * u * u * p[0] + 3.0 * u * u * s * p[1] + 3.0 * u * s * s * p[2] + s * s * s * p[3];
  };
  constexpr int kSteps = 20000;
  double ref = -1.0;
  double min_abs = std::fabs(F(0.0));
  for (int i = 0; i < kSteps && ref < 0.0; ++i) {
    double lo = double(i) / kSteps, hi = double(i + 1) / kSteps;
    min_abs = std::min(min_abs, std::fabs(F(hi)));
    if ((F(lo) < 0.0) == (F(hi) < 0.0)) continue;
    for (int k = 0; k < 60; ++k) {
      const double m = 0.5 * (lo + hi);
      ((F(m) < 0.0) == (F(lo) < 0.0) ? lo : hi) = m;
    }
    ref = 0.5 * (lo + hi);
  }
  float s = -1.0f;
  const bool found = lr81_first_root(b, 0.0f, 1e-6f, s);
  if (ref >= 0.0) {
    RC_ASSERT(found);
    // An earlier root the scan missed can only be a (near-)tangent touch: the curve is ~0 there.
    if (std::fabs(double(s) - ref) > 1e-4) RC_ASSERT(double(s) < ref && std::fabs(F(s)) < 1e-5);
  } else if (found) {
    RC_ASSERT(std::fabs(F(s)) < 1e-5);  // a touch the scan stepped over
  }
}

RC_GTEST_PROP(ExactIsoProperty, AnalyticGradientEqualsFiniteDifferences, ()) {
  const CellCorners c = random_corners(100.0f);
  const vec3 f = vec3(0.05f) + 0.9f * random_unit_point();
  const vec3 g = trilinear_gradient_local(c, f);
  const auto F = [&](const glm::dvec3& q) {
    // The interpolant in double, so the difference quotient is not rounding noise.
    double r = 0.0;
    for (int i = 0; i < 8; ++i) {
      r += double(c.v[i]) * ((i & 1) ? q.x : 1.0 - q.x) * ((i & 2) ? q.y : 1.0 - q.y) * ((i & 4) ? q.z : 1.0 - q.z);
    }
    return r;
  };
  const double h = 1e-4;
  const glm::dvec3 fd((F(glm::dvec3(f) + glm::dvec3(h, 0, 0)) - F(glm::dvec3(f) - glm::dvec3(h, 0, 0))) / (2 * h),
                      (F(glm::dvec3(f) + glm::dvec3(0, h, 0)) - F(glm::dvec3(f) - glm::dvec3(0, h, 0))) / (2 * h),
                      (F(glm::dvec3(f) + glm::dvec3(0, 0, h)) - F(glm::dvec3(f) - glm::dvec3(0, 0, h))) / (2 * h));
  const double scale = std::max(glm::length(fd), 1.0);
  RC_ASSERT(glm::length(glm::dvec3(g) - fd) <= 1e-3 * scale);
}

// The walk visits face-adjacent cells in order, each stretch following the last, each containing the
// ray's points of its stretch.
RC_GTEST_PROP(ExactIsoProperty, CellWalkVisitsConsecutiveCells, ()) {
  const auto coord = [] { return float(*rc::gen::inRange(-2000, 2001)) / 100.0f; };
  Ray ray;
  ray.origin = vec3(coord(), coord(), coord());
  vec3 d(coord(), coord(), coord());
  RC_PRE(glm::length(d) > 0.1f);
  ray.dir = glm::normalize(d);
  const vec3 inv_voxel(1.0f / (0.5f + float(*rc::gen::inRange(0, 3))), 1.0f, 0.5f);
  CellWalk w(ray, inv_voxel, 0.0f);
  RC_ASSERT(w.t0 <= 1e-4f && w.t1 >= -1e-4f);
  float prev_t1 = w.t1;
  for (int n = 0; n < 40; ++n) {
    const ivec3 prev = w.cell;
    w.advance();
    const ivec3 step = glm::abs(w.cell - prev);
    RC_ASSERT(step.x + step.y + step.z == 1);
    RC_ASSERT(std::fabs(w.t0 - prev_t1) <= 1e-4f * std::max(1.0f, std::fabs(prev_t1)));
    RC_ASSERT(w.t1 >= w.t0 - 1e-4f);
    const float tm = 0.5f * (w.t0 + w.t1);
    const vec3 u = w.uo + tm * w.ud - vec3(w.cell);
    RC_ASSERT(glm::all(glm::greaterThanEqual(u, vec3(-1e-3f))) && glm::all(glm::lessThanEqual(u, vec3(1.0f + 1e-3f))));
    prev_t1 = w.t1;
  }
}

// ---- whole renders -------------------------------------------------------------------------------

// The clamped trilinear interpolant of the volume at world p (spacing 1), in double.
double interpolant(const Volume& v, const glm::dvec3& p) {
  const ivec3 d = v.dims();
  const glm::dvec3 u = glm::clamp(p - 0.5, glm::dvec3(0.0), glm::dvec3(d - 1));
  const ivec3 i0 = glm::min(ivec3(glm::floor(u)), d - 2);
  const glm::dvec3 f = u - glm::dvec3(i0);
  double r = 0.0;
  for (int i = 0; i < 8; ++i) {
    const ivec3 o(i & 1, (i >> 1) & 1, (i >> 2) & 1);
    const ivec3 q = i0 + o;
    r += double(v.value(q.x, q.y, q.z)) * (o.x ? f.x : 1 - f.x) * (o.y ? f.y : 1 - f.y) * (o.z ? f.z : 1 - f.z);
  }
  return r;
}

// The reference root of the clamped trilinear interpolant, 1/1000 voxel apart.
double reference_root(const Volume& v, const Ray& ray, double iso) {
  return first_crossing(v, ray, iso, 1e-3, [&](const glm::dvec3& p) { return interpolant(v, p); });
}

TEST(ExactIso, PlaneHitsWithinATenThousandthOfAVoxel) {
  // Linear in the voxel coordinates, so the interpolant is exactly linear inside the centres' box; the
  // z term dominates, so rays from above cross it once.
  const ivec3 dims(40, 36, 44);
  const Volume v = field(dims, [](double x, double y, double z) { return 2.0 * z + 0.3 * x - 0.2 * y; });
  const float iso = 40.0f;
  const glm::dvec3 g(0.3, -0.2, 2.0);
  for (const vec3 dir : {vec3(0, 0, -1), vec3(0.3f, 0.2f, -1.0f), vec3(-0.25f, 0.4f, -1.0f)}) {
    const int size = 40;
    const Camera cam = ortho(0.5f * vec3(dims), dir, 30.0f, 80.0f);
    const RayGenerator gen = make_ray_generator(cam, size, size);
    const Frame f = render_iso(v, cam, iso, IsoMethod::Exact, size);
    const DepthErrors e = depth_errors(f, size, [&](int x, int y) {
      const Ray r = gen.ray(x, y);
      // g·(p - 0.5) = iso, p = o + t d.
      const double t = (iso - glm::dot(g, glm::dvec3(r.origin) - 0.5)) / glm::dot(g, glm::dvec3(r.dir));
      const glm::dvec3 u = glm::dvec3(r.origin) + t * glm::dvec3(r.dir) - 0.5;
      const bool inside = glm::all(glm::greaterThan(u, glm::dvec3(0.5))) &&
                          glm::all(glm::lessThan(u, glm::dvec3(dims) - 1.5));
      return inside ? t : NAN;
    });
    EXPECT_GT(e.checked, 600) << "direction " << dir.x << "," << dir.y;
    EXPECT_EQ(e.missed, 0);
    EXPECT_LE(e.max, 1e-4) << "direction " << dir.x << "," << dir.y << " mean " << e.mean;
  }
}

TEST(ExactIso, ProductOfLinearFactorsMatchesTheReferenceRoot) {
  // (x - a)(y - b)(z - c) is trilinear everywhere, so the interpolant is the product itself inside the
  // centres' box; iso ≠ 0 makes the ray polynomial a genuine cubic in each cell.
  const ivec3 dims(24, 22, 20);
  const double a = 11.3, b = 9.7, c = 10.45;
  const Volume v = field(dims, [&](double x, double y, double z) { return (x - a) * (y - b) * (z - c) / 50.0; });
  const int size = 32;
  int hits = 0;
  for (const vec3 dir : {vec3(1, 0.7f, -0.9f), vec3(-0.6f, 1, 0.8f)}) {
    for (const float iso : {2.0f, -3.5f}) {
      const Camera cam = ortho(0.5f * vec3(dims), dir, 22.0f, 60.0f);
      const RayGenerator gen = make_ray_generator(cam, size, size);
      const Frame f = render_iso(v, cam, iso, IsoMethod::Exact, size);
      const DepthErrors e = depth_errors(f, size, [&](int x, int y) {
        const double t = reference_root(v, gen.ray(x, y), iso);
        return t >= 0.0 ? t : NAN;
      });
      EXPECT_EQ(e.missed, 0) << "iso " << iso;
      EXPECT_LE(e.max, 1e-4) << "iso " << iso << " mean " << e.mean;
      hits += e.checked;
    }
  }
  EXPECT_GT(hits, 1000);
}

TEST(ExactIso, SphereDistanceFieldHitsTheAnalyticSphere) {
  const ivec3 dims(96, 96, 96);
  const GeneratedVolume g = generate_volume("sphere", dims, 1);  // distance to the box centre
  const vec3 centre = 0.5f * vec3(dims);
  const int size = 48;
  for (const vec3 dir : {vec3(0, 0, -1), vec3(0.5f, -0.3f, -1.0f)}) {
    const Camera cam = ortho(centre, dir, 96.0f, 150.0f);
    const RayGenerator gen = make_ray_generator(cam, size, size);
    // Radius 40: the trilinear interpolant of |p| lies within 1/(4R) of the sphere (its error at a cell
    // centre is the Laplacian 2/R over 8), so the root is within 0.01 voxel along steep rays.
    const Frame exact = render_iso(g.intensity, cam, 40.0f, IsoMethod::Exact, size);
    const Frame sampled = render_iso(g.intensity, cam, 40.0f, IsoMethod::Sampled, size);
    const DepthErrors e = depth_errors(exact, size, sphere_depth(gen, centre, 40.0));
    const DepthErrors es = depth_errors(sampled, size, sphere_depth(gen, centre, 40.0));
    EXPECT_GT(e.checked, 400);
    EXPECT_EQ(e.missed, 0);
    EXPECT_LE(e.max, 0.01) << "mean " << e.mean;
    std::printf("sphere R=40 dir (%g,%g,%g): exact max %.6f mean %.6f; sampled (step 0.5) max %.6f mean %.6f\n",
                dir.x, dir.y, dir.z, e.max, e.mean, es.max, es.mean);
  }
  // Radius 8: the interpolant itself is up to ~1/(4R) = 0.03 voxel off the sphere, but its root is found
  // to 1e-4 (the reference root of the same interpolant).
  {
    const ivec3 small(24, 24, 24);
    const GeneratedVolume s = generate_volume("sphere", small, 1);
    const vec3 c = 0.5f * vec3(small);
    const int px = 32;
    const Camera cam = ortho(c, vec3(0.2f, 0.1f, -1.0f), 24.0f, 50.0f);
    const RayGenerator gen = make_ray_generator(cam, px, px);
    const Frame exact = render_iso(s.intensity, cam, 8.0f, IsoMethod::Exact, px);
    const DepthErrors ref = depth_errors(exact, px, [&](int x, int y) {
      const double t = reference_root(s.intensity, gen.ray(x, y), 8.0);
      return t >= 0.0 ? t : NAN;
    });
    const DepthErrors ana = depth_errors(exact, px, sphere_depth(gen, c, 8.0));
    EXPECT_GT(ref.checked, 100);
    EXPECT_EQ(ref.missed, 0);
    EXPECT_LE(ref.max, 1e-4) << "mean " << ref.mean;
    EXPECT_LE(ana.max, 0.25 / 8.0 + 0.01) << "mean " << ana.mean;
  }
}

TEST(ExactIso, ThinSheetIsFoundByExactAndMissedBySampled) {
  // One voxel plane z = 29 at 100, 0 elsewhere; iso 80: the interpolant exceeds 80 only within 0.2 voxel
  // of the plane's centres, so a ray down z crosses the surface twice 0.4 voxel apart. With step 0.75 the
  // samples fall at u = 31.5 - 0.75 k: 29.25 (75) and 28.5 (50) straddle the sheet, both below 80.
  const ivec3 dims(16, 16, 32);
  const Volume v = field(dims, [](double, double, double z) { return z == 29.0 ? 100.0 : 0.0; });
  const int size = 16;
  const Camera cam = ortho(0.5f * vec3(dims), vec3(0, 0, -1), 16.0f, 26.0f);  // eye at z = 42
  const Frame exact = render_iso(v, cam, 80.0f, IsoMethod::Exact, size, 0.75f);
  const Frame sampled = render_iso(v, cam, 80.0f, IsoMethod::Sampled, size, 0.75f);
  int found = 0, missed = 0;
  for (int i = 0; i < size * size; ++i) {
    found += exact.image.rgba[i].w == 1.0f;
    missed += sampled.image.rgba[i].w == 0.0f;
    // First crossing from above at u = 29.2, world z = 29.7: t = 42 - 29.7.
    EXPECT_NEAR(exact.image.channels.at("depth")[i], 12.3f, 1e-4f);
  }
  EXPECT_EQ(found, size * size) << "exact misses the sheet";
  EXPECT_EQ(missed, size * size) << "sampled finds the sheet: the test no longer shows the difference";
  // At step 0.5 a sample lands on the plane's centres (u = 29) and the sampled method finds it too.
  const Frame fine = render_iso(v, cam, 80.0f, IsoMethod::Sampled, size, 0.5f);
  EXPECT_EQ(fine.image.rgba[0].w, 1.0f);
}

TEST(ExactIso, EveryMethodFindsTheSameRootsOnTheSphere) {
  // The spans of the skipping methods start and end in different cells; the roots must not move.
  const GeneratedVolume g = generate_volume("sphere", ivec3(61, 53, 47), 1);
  const Camera cam = default_camera(g.intensity.desc().extent());
  const Frame ref = render_iso(g.intensity, cam, 15.0f, IsoMethod::Exact, 41, 0.5f, SkipMethod::None);
  const auto& d0 = ref.image.channels.at("depth");
  int hits = 0;
  for (float d : d0) hits += d >= 0.0f;
  EXPECT_GT(hits, 80);
  for (SkipMethod m : {SkipMethod::BBox, SkipMethod::Octree, SkipMethod::SparseLeap}) {
    const Frame f = render_iso(g.intensity, cam, 15.0f, IsoMethod::Exact, 41, 0.5f, m);
    EXPECT_EQ(f.image.channels.at("depth"), d0) << to_string(m);
    EXPECT_LT(f.stats.samples, ref.stats.samples) << to_string(m) << " skips no cells";
  }
}

// Distributed (sort-last): each rank accepts the roots in its region box only, so over a k-d split of
// the volume exactly one rank finds a ray's first root, at the single-process depth, bit for bit.
TEST(ExactIso, RegionsOfAKdSplitFindEachRootOnce) {
  const GeneratedVolume g = generate_volume("sphere", ivec3(40, 36, 32), 1);
  const TransferFunction tf = default_transfer_function(0, 40);
  const Camera cam = default_camera(g.intensity.desc().extent());
  RenderSettings s;
  s.mode = RenderMode::Iso;
  s.iso = 12.0f;
  LabelSet storage;
  const Scene scene{&g.intensity, nullptr, &tf, nullptr, cam};
  RayCaster<DenseSampler<float, std::uint8_t>> caster;
  caster.p = make_cast_params(scene, s, storage);
  caster.volume.volume = DenseGrid<float>{g.intensity.as<float>(), g.intensity.dims(), vec3(1.0f)};
  // Four regions: x split at 20 (through the sphere's centre plane), then y at 17 on the left.
  const float inf = INFINITY;
  const SampleClip regions[] = {{true, vec3(-inf), vec3(20.0f, 17.0f, inf)},
                                {true, vec3(-inf, 17.0f, -inf), vec3(20.0f, inf, inf)},
                                {true, vec3(20.0f, -inf, -inf), vec3(inf)}};
  const int size = 48;
  const RayGenerator gen = make_ray_generator(cam, size, size);
  const Box3 vbox{vec3(0.0f), g.intensity.desc().extent()};
  int hits = 0, shared = 0;
  for (int y = 0; y < size; ++y) {
    for (int x = 0; x < size; ++x) {
      Ray ray;
      float t_entry, t_exit;
      if (!pixel_span(gen, vbox, x, y, ray, t_entry, t_exit)) continue;
      std::uint32_t misses = 0;
      RayAccum whole;
      detail::cast_pixel(caster, SkipInputs{}, 0, ray, t_entry, t_exit, whole, misses);
      int found = 0;
      std::set<int> owners;
      for (int r = 0; r < 3; ++r) {
        SkipInputs skip;
        skip.clip = regions[r];
        RayAccum part;
        detail::cast_pixel(caster, skip, 0, ray, t_entry, t_exit, part, misses);
        if (part.hit_t < 0.0f) continue;
        ++found;
        // A rank may also find a later root of its own; the one at the single-process depth is unique.
        if (part.hit_t == whole.hit_t) owners.insert(r);
      }
      if (whole.hit_t < 0.0f) continue;
      ++hits;
      EXPECT_EQ(owners.size(), 1u) << x << "," << y;
      shared += found > 1;
    }
  }
  EXPECT_GT(hits, 150);
  EXPECT_GT(shared, 0) << "no ray crosses the surface in two regions: the split tests nothing";
}

}  // namespace
}  // namespace sl
