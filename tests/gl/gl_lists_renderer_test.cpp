// `--lists gl` through the renderers: InCoreRenderer and OutOfCoreRenderer with the GL builder plugged in
// (set_list_builder) render the very image they render with their own CPU builder.
#include <gtest/gtest.h>

#include <cstring>
#include <memory>

#include "core/scene/generate.h"
#include "cache/out_of_core/renderer.h"
#include "core/frame/in_core_renderer.h"
#include "gl/gl_segment_list_builder.h"
#include "tests/gl/gl_test_util.h"

namespace sl {
namespace {

ListBuilder gl_builder(GlContext& ctx) {
  auto b = std::make_shared<GlSegmentListBuilder>(ctx);
  return [b, &ctx](const OccupancyGeometry& g, std::span<const VisibilityEntry> order, const RayGenerator& gen,
                   SegmentListBuffer& out, float eps) {
    ctx.make_current();
    return b->build_segment_lists(g, order, gen, out, eps).lists;
  };
}

std::size_t differing_pixels(const Frame& a, const Frame& b) {
  std::size_t n = 0;
  for (std::size_t i = 0; i < a.image.rgba.size(); ++i) {
    n += std::memcmp(&a.image.rgba[i], &b.image.rgba[i], sizeof(vec4)) != 0;
  }
  return n;
}

TEST(GlListsRenderer, InCoreRendererWithGlListsRendersTheCpuListsImage) {
  SL_REQUIRE_GL(ctx);
  GeneratedVolume g = generate_volume("neurites", ivec3(61, 47, 53), 3);
  const TransferFunction tf = default_transfer_function(0.0f, 255.0f);
  const LabelSet enabled = parse_enable_spec("fraction:0.5:1", g.label_count);
  for (const Camera& cam : {test::gl_perspective(vec3(90.0f, 60.0f, 120.0f), vec3(30.0f, 23.0f, 26.0f)),
                            test::gl_perspective(vec3(25.0f, 20.0f, 30.0f), vec3(50.0f, 25.0f, 5.0f), 90.0f),
                            test::gl_orthographic(vec3(-40.0f, 30.0f, 100.0f), vec3(30.0f, 23.0f, 26.0f), 90.0f)}) {
    Scene scene{&g.intensity, &g.labels, &tf, &enabled, cam};
    RenderSettings s;
    s.width = 72;
    s.height = 56;
    s.block = 4;
    InCoreRenderer cpu;
    InCoreRenderer gl;
    gl.set_list_builder(gl_builder(*ctx));
    const Frame a = cpu.render(scene, s);
    const Frame b = gl.render(scene, s);
    EXPECT_EQ(differing_pixels(a, b), 0u);
    EXPECT_EQ(a.stats.samples, b.stats.samples);
    EXPECT_EQ(a.stats.events, b.stats.events);
    RenderSettings none = s;
    none.method = SkipMethod::None;
    EXPECT_LT(b.stats.samples, cpu.render(scene, none).stats.samples);  // the lists really skip
    float alpha = 0;
    for (const vec4& c : b.image.rgba) alpha += c.w;
    EXPECT_GT(alpha, 1.0f);
  }
}

TEST(GlListsRenderer, OutOfCoreWithGlListsConvergesToTheCpuListsImage) {
  SL_REQUIRE_GL(ctx);
  GeneratedVolume g = generate_volume("neurites", ivec3(64, 64, 64), 8);
  auto volume = std::make_shared<const Volume>(std::move(g.intensity));
  const TransferFunction tf = default_transfer_function(0.0f, 255.0f);
  const Camera cam = default_camera(volume->desc().extent());
  RenderSettings s;
  s.width = s.height = 48;
  OutOfCoreSettings os;
  os.brick = 16;
  os.lod = 0;
  os.cache_mb = 16;
  auto run = [&](bool with_gl) {
    OutOfCoreRenderer r(std::make_shared<MemoryVolumeSource>(volume, nullptr, "n"), os, 16);
    if (with_gl) r.set_list_builder(gl_builder(*ctx));
    Frame f;
    for (int i = 0; i < 60; ++i) {
      f = r.render(OutOfCoreScene{&tf, nullptr, cam}, s);
      if (r.converged()) break;
      r.wait_for_loads();
    }
    EXPECT_TRUE(r.converged());
    return f;
  };
  const Frame a = run(false);
  const Frame b = run(true);
  EXPECT_EQ(differing_pixels(a, b), 0u);
  EXPECT_EQ(a.stats.samples, b.stats.samples);
}

}  // namespace
}  // namespace sl
