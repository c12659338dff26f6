// Blinn–Phong lighting (core/cast/shading.h): VTK's model with a headlight, the gradient-magnitude guard,
// and lit DVR renders.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "core/scene/generate.h"
#include "core/frame/in_core_renderer.h"
#include "core/scene/labels.h"
#include "core/cast/shading.h"

namespace sl {
namespace {

TEST(Shading, VtkDefaultsAndTheHeadlightModel) {
  const Lighting l;  // VTK's defaults
  EXPECT_EQ(l.ambient, 0.1f);
  EXPECT_EQ(l.diffuse, 0.7f);
  EXPECT_EQ(l.specular, 0.2f);
  EXPECT_EQ(l.shininess, 10.0f);
  const vec3 rgb(0.5f, 0.25f, 1.0f), view(0, 0, -1);
  // Facing the viewer (either orientation: two-sided): ambient + diffuse, plus the full white specular.
  for (const vec3 g : {vec3(0, 0, 3), vec3(0, 0, -3)}) {
    const vec3 c = blinn_phong(rgb, g, view, l);
    for (int i = 0; i < 3; ++i) EXPECT_FLOAT_EQ(c[i], rgb[i] * 0.8f + 0.2f);
  }
  // At 60 degrees n·l = 1/2.
  const vec3 c = blinn_phong(rgb, vec3(std::sqrt(3.0f), 0, 1), view, l);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(c[i], rgb[i] * (0.1f + 0.35f) + 0.2f * std::pow(0.5f, 10.0f), 1e-6f);
  // Edge on: ambient only.
  const vec3 e = blinn_phong(rgb, vec3(1, 0, 0), view, l);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(e[i], rgb[i] * 0.1f, 1e-6f);
}

TEST(Shading, GradientGuardKeepsTheUnlitColour) {
  Lighting l;
  l.min_gradient = 0.5f;
  const vec3 rgb(0.3f, 0.6f, 0.9f);
  EXPECT_EQ(blinn_phong(rgb, vec3(0.2f, 0.1f, 0.3f), vec3(0, 0, -1), l), rgb);  // |g| < guard
  EXPECT_EQ(blinn_phong(rgb, vec3(0.0f), vec3(0, 0, -1), Lighting{}), rgb);      // no normal at all
  EXPECT_NE(blinn_phong(rgb, vec3(0, 0, 2), vec3(0, 0, -1), l), rgb);
}

Frame render(const Volume& v, const TransferFunction& tf, bool shade) {
  Scene scene{&v, nullptr, &tf, nullptr, default_camera(v.desc().extent())};
  RenderSettings s;
  s.width = s.height = 40;
  s.method = SkipMethod::None;
  s.lighting.enabled = shade;
  InCoreRenderer r;
  return r.render(scene, s);
}

TEST(Shading, HomogeneousVolumeIsUnchangedByLighting) {
  // Every gradient is zero: the guard leaves every sample unlit, so the image is bit for bit the unlit one.
  Volume v(VolumeDesc{ivec3(20, 18, 16), vec3(1.0f), VoxelType::U8});
  for (int z = 0; z < 16; ++z)
    for (int y = 0; y < 18; ++y)
      for (int x = 0; x < 20; ++x) v.set(x, y, z, 90);
  const TransferFunction tf({{0, {1, 0.5f, 0.2f, 0.05f}}, {255, {1, 0.5f, 0.2f, 0.05f}}});
  const Frame a = render(v, tf, false), b = render(v, tf, true);
  ASSERT_EQ(a.image.rgba.size(), b.image.rgba.size());
  EXPECT_EQ(std::memcmp(a.image.rgba.data(), b.image.rgba.data(), a.image.rgba.size() * sizeof(vec4)), 0);
}

TEST(Shading, LitSphereIsBrightestWhereItFacesTheViewer) {
  const GeneratedVolume g = generate_volume("sphere", ivec3(48, 48, 48), 1);
  // Opaque shell around radius 15 (a distance field), colour 0.5 grey.
  const TransferFunction tf({{0, {0.5f, 0.5f, 0.5f, 0}}, {14, {0.5f, 0.5f, 0.5f, 0}}, {15, {0.5f, 0.5f, 0.5f, 1}},
                             {16, {0.5f, 0.5f, 0.5f, 0}}, {100, {0.5f, 0.5f, 0.5f, 0}}});
  const Frame unlit = render(g.intensity, tf, false), lit = render(g.intensity, tf, true);
  // The central ray meets the shell head-on: diffuse 0.7 + ambient 0.1 of the colour, plus 0.2 specular.
  const vec4 c = lit.image.at(20, 20), u = unlit.image.at(20, 20);
  ASSERT_GT(u.w, 0.9f);
  EXPECT_EQ(c.w, u.w);  // lighting changes colour, never opacity
  EXPECT_NEAR(c.x, u.x * 0.8f + 0.2f * u.w, 0.05f);
  // Towards the silhouette the shell turns away from the light: darker than the centre.
  int darker = 0, lit_px = 0;
  for (int y = 0; y < 40; ++y) {
    for (int x = 0; x < 40; ++x) {
      const vec4 p = lit.image.at(x, y);
      if (p.w < 0.5f) continue;
      ++lit_px;
      darker += p.x < c.x - 0.05f;
    }
  }
  EXPECT_GT(lit_px, 100);
  EXPECT_GT(darker, lit_px / 4);
}

// Lit labels (--mode labels --shade): a label's surface is shaded with the gradient of its mask. A label
// filling z < 10 seen from above along -z: the mask's gradient there is along z, so the first
// (opaque) sample is lit head-on: colour * (ambient + diffuse) + specular.
TEST(Shading, LitLabelsShadeEachLabelsSurfaceByItsMask) {
  const ivec3 dims(20, 20, 20);
  Volume v(VolumeDesc{dims, vec3(1.0f), VoxelType::U8}), lab(VolumeDesc{dims, vec3(1.0f), VoxelType::U8});
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x) {
        v.set(x, y, z, 200);
        lab.set(x, y, z, z < 10 ? 1 : 0);
      }
  const TransferFunction tf({{0, {1, 1, 1, 1}}, {255, {1, 1, 1, 1}}});
  Camera cam;
  cam.projection = Projection::Orthographic;
  cam.center = vec3(10.0f, 10.0f, 5.0f);
  cam.eye = vec3(10.0f, 10.0f, 40.0f);
  cam.up = vec3(0, 1, 0);
  cam.height = 10.0f;
  Scene scene{&v, &lab, &tf, nullptr, cam};
  RenderSettings s;
  s.width = s.height = 8;
  s.mode = RenderMode::Labels;
  s.method = SkipMethod::None;
  InCoreRenderer r;
  const Frame unlit = r.render(scene, s);
  s.lighting.enabled = true;
  const Frame lit = r.render(scene, s);
  const vec3 base = label_color(1);
  for (int i = 0; i < 64; ++i) {
    ASSERT_EQ(unlit.image.rgba[i].w, 1.0f);
    EXPECT_NEAR(unlit.image.rgba[i].x, base.x, 1e-5f);
    EXPECT_EQ(lit.image.rgba[i].w, 1.0f);
    EXPECT_NEAR(lit.image.rgba[i].x, base.x * 0.8f + 0.2f, 1e-4f);
    EXPECT_NEAR(lit.image.rgba[i].y, base.y * 0.8f + 0.2f, 1e-4f);
    EXPECT_NEAR(lit.image.rgba[i].z, base.z * 0.8f + 0.2f, 1e-4f);
  }
}

}  // namespace
}  // namespace sl
