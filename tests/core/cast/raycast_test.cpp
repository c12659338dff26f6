// The ray caster against closed forms: Beer–Lambert through a slab and its DVR depth, isosurface depth on a sphere,
// MIP, and thread-count determinism (DESIGN.md "Ray casting" conventions).
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstring>

#include "core/scene/generate.h"
#include "core/frame/in_core_renderer.h"

namespace sl {
namespace {

Camera ortho_down_z(const vec3& extent, float height) {
  Camera c;
  c.projection = Projection::Orthographic;
  c.center = 0.5f * extent;
  c.eye = vec3(c.center.x, c.center.y, extent.z + 10.0f);
  c.up = vec3(0, 1, 0);
  c.height = height;
  return c;
}

// A u8 volume of one value.
Volume uniform_u8(const ivec3& dims, int value) {
  VolumeDesc d;
  d.dims = dims;
  d.type = VoxelType::U8;
  Volume v(d);
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x) v.set(x, y, z, value);
  return v;
}

TEST(RayCast, ConstantSlabMatchesBeerLambert) {
  const Volume v = uniform_u8(ivec3(16, 16, 64), 100);
  const VolumeDesc& d = v.desc();
  const float a = 0.05f;  // opacity per unit (min spacing) length
  TransferFunction tf({{0.0f, {0.2f, 0.6f, 1.0f, a}}, {255.0f, {0.2f, 0.6f, 1.0f, a}}});
  for (float step : {0.5f, 0.25f, 1.0f}) {
    Scene scene{&v, nullptr, &tf, nullptr, ortho_down_z(d.extent(), 8.0f)};
    RenderSettings s;
    s.width = s.height = 8;
    s.method = SkipMethod::None;
    s.step = step;
    InCoreRenderer r;
    const Frame f = r.render(scene, s);
    // Ray length 64 along z; samples t_k < 64, k = 0 .. 64/dt - 1, each α' = 1 − (1 − a)^step.
    const float expected_alpha = 1.0f - std::pow(1.0f - a, 64.0f);
    const vec4 c = f.image.at(4, 4);
    EXPECT_NEAR(c.w, expected_alpha, 2e-5f) << "step " << step;
    EXPECT_NEAR(c.x, 0.2f * expected_alpha, 2e-5f);
    EXPECT_NEAR(c.z, 1.0f * expected_alpha, 2e-5f);
    EXPECT_EQ(f.image.channels.at("samples")[4 * 8 + 4], 64.0f / step);
  }
}

TEST(RayCast, DvrDepthIsTheFirstSampleWhereTheOpacityReachesAHalf) {
  const Volume v = uniform_u8(ivec3(8, 8, 64), 100);
  const VolumeDesc& d = v.desc();
  for (const float a : {0.05f, 0.2f, 0.005f}) {
    TransferFunction tf({{0.0f, {1, 1, 1, a}}, {255.0f, {1, 1, 1, a}}});
    for (const float step : {0.5f, 0.25f, 1.0f}) {
      Scene scene{&v, nullptr, &tf, nullptr, ortho_down_z(d.extent(), 8.0f)};
      RenderSettings s;
      s.width = s.height = 8;
      s.method = SkipMethod::None;
      s.step = step;
      InCoreRenderer r;
      const Frame f = r.render(scene, s);
      ASSERT_TRUE(f.image.channels.count("depth"));
      // After samples 0..k the opacity is 1 − (1 − a)^((k+1)·step): it reaches 0.5 at the first k with
      // (k+1)·step ≥ L = log 0.5 / log(1 − a); sample k is at t = 10 + k·step (the eye is 10 above).
      const double L = std::log(0.5) / std::log(1.0 - double(a));
      const double k = std::ceil(L / step) - 1.0;
      const float expected = k * step < 64.0 ? float(10.0 + k * step) : -1.0f;  // a = 0.005: never (0.27)
      for (int i : {0, 27, 63}) {
        EXPECT_NEAR(f.image.channels.at("depth")[i], expected, 1e-4f) << "a " << a << ", step " << step;
      }
    }
  }
  // MIP has no depth.
  TransferFunction tf({{0.0f, {1, 1, 1, 1}}, {255.0f, {1, 1, 1, 1}}});
  RenderSettings s;
  s.width = s.height = 8;
  s.mode = RenderMode::Mip;
  InCoreRenderer r;
  EXPECT_FALSE(r.render(Scene{&v, nullptr, &tf, nullptr, ortho_down_z(d.extent(), 8.0f)}, s).image.channels.count("depth"));
}

TEST(RayCast, AnisotropicSpacingUsesMinSpacingForOpacityCorrection) {
  VolumeDesc d;
  d.dims = ivec3(8, 8, 32);
  d.spacing = vec3(1.0f, 1.0f, 2.0f);
  d.type = VoxelType::U8;
  Volume v(d);
  for (int z = 0; z < 32; ++z)
    for (int y = 0; y < 8; ++y)
      for (int x = 0; x < 8; ++x) v.set(x, y, z, 10);
  const float a = 0.02f;
  TransferFunction tf({{0.0f, {1, 1, 1, a}}, {255.0f, {1, 1, 1, a}}});
  Scene scene{&v, nullptr, &tf, nullptr, ortho_down_z(d.extent(), 4.0f)};
  RenderSettings s;
  s.width = s.height = 4;
  s.method = SkipMethod::None;
  InCoreRenderer r;
  const Frame f = r.render(scene, s);
  // World depth 64, reference length min spacing = 1.
  EXPECT_NEAR(f.image.at(2, 2).w, 1.0f - std::pow(1.0f - a, 64.0f), 2e-5f);
}

TEST(RayCast, IsosurfaceDepthOnSphereWithinAVoxelFraction) {
  GeneratedVolume g = generate_volume("sphere", ivec3(64, 64, 64), 1);
  const Volume& v = g.intensity;
  TransferFunction tf({{0.0f, {1, 1, 1, 1}}, {64.0f, {1, 1, 1, 1}}});
  const vec3 ext = v.desc().extent();
  Scene scene{&v, nullptr, &tf, nullptr, ortho_down_z(ext, 64.0f)};
  RenderSettings s;
  s.width = s.height = 64;
  s.mode = RenderMode::Iso;
  s.iso = 20.0f;
  s.method = SkipMethod::None;
  InCoreRenderer r;
  const Frame f = r.render(scene, s);
  const auto& depth = f.image.channels.at("depth");
  int checked = 0;
  for (int y = 0; y < 64; ++y) {
    for (int x = 0; x < 64; ++x) {
      // Orthographic pixel centre in world x/y; the sphere is centred at ext/2 with radius 20.
      const float wx = (x + 0.5f) - 32.0f, wy = 32.0f - (y + 0.5f);
      const float r2 = wx * wx + wy * wy;
      if (r2 > 18.0f * 18.0f) continue;  // stay clear of grazing hits
      const float expected = (ext.z + 10.0f) - (32.0f + std::sqrt(400.0f - r2));
      EXPECT_NEAR(depth[y * 64 + x], expected, 0.05f) << x << "," << y;
      EXPECT_NEAR(f.image.at(x, y).w, 1.0f, 1e-6f);
      ++checked;
    }
  }
  EXPECT_GT(checked, 900);
  EXPECT_EQ(depth[0], -1.0f);  // corner ray misses the sphere
}

TEST(RayCast, MipTakesTheMaximumAlongTheRay) {
  VolumeDesc d;
  d.dims = ivec3(8, 8, 40);
  d.type = VoxelType::U8;
  Volume v(d);
  for (int z = 0; z < 40; ++z)
    for (int y = 0; y < 8; ++y)
      for (int x = 0; x < 8; ++x) v.set(x, y, z, z == 20 ? 200 : 30);
  TransferFunction tf({{0.0f, {0, 0, 0, 0}}, {255.0f, {1, 0.5f, 0.25f, 0}}});
  Scene scene{&v, nullptr, &tf, nullptr, ortho_down_z(d.extent(), 8.0f)};
  RenderSettings s;
  s.width = s.height = 8;
  s.mode = RenderMode::Mip;
  s.method = SkipMethod::None;
  InCoreRenderer r;
  const Frame f = r.render(scene, s);
  // Samples hit voxel 20's centre exactly (t_k on the half-voxel grid), so the max is 200.
  const vec4 c = f.image.at(3, 3);
  const vec4 expected = tf.evaluate(200.0f);
  EXPECT_NEAR(c.x, expected.x, 1e-3f);
  EXPECT_NEAR(c.y, expected.y, 1e-3f);
  EXPECT_NEAR(c.z, expected.z, 1e-3f);
  EXPECT_EQ(c.w, 1.0f);
}

TEST(RayCast, ImageIsBitIdenticalForAnyThreadCount) {
  GeneratedVolume g = generate_volume("neurites", ivec3(64, 56, 48), 3);
  TransferFunction tf = default_transfer_function(0, 255);
  Scene scene{&g.intensity, &g.labels, &tf, nullptr, default_camera(g.intensity.desc().extent())};
  RenderSettings s;
  s.width = 96;
  s.height = 80;
  s.method = SkipMethod::None;
  Frame one, two;
  {
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, 1);
    one = InCoreRenderer().render(scene, s);
  }
  {
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, 2);
    two = InCoreRenderer().render(scene, s);
  }
  ASSERT_EQ(one.image.rgba.size(), two.image.rgba.size());
  EXPECT_EQ(0, std::memcmp(one.image.rgba.data(), two.image.rgba.data(), one.image.rgba.size() * sizeof(vec4)));
  EXPECT_EQ(one.stats.samples, two.stats.samples);
  float sum = 0;
  for (const vec4& c : one.image.rgba) sum += c.w;
  EXPECT_GT(sum, 10.0f);  // the neurites are visible
}

TEST(RayCast, EarlyRayTerminationStopsAtThreshold) {
  VolumeDesc d;
  d.dims = ivec3(4, 4, 128);
  Volume v(d);
  for (int z = 0; z < 128; ++z)
    for (int y = 0; y < 4; ++y)
      for (int x = 0; x < 4; ++x) v.set(x, y, z, 255);
  TransferFunction tf({{0.0f, {1, 1, 1, 0.5f}}, {255.0f, {1, 1, 1, 0.5f}}});
  Scene scene{&v, nullptr, &tf, nullptr, ortho_down_z(d.extent(), 4.0f)};
  RenderSettings s;
  s.width = s.height = 4;
  s.method = SkipMethod::None;
  s.ert = true;
  const Frame f = InCoreRenderer().render(scene, s);
  EXPECT_GE(f.image.at(1, 1).w, 0.99f);
  EXPECT_LT(f.image.channels.at("samples")[5], 20.0f);  // far fewer than 256
}

}  // namespace
}  // namespace sl
