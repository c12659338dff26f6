// Images cast from GL-built lists equal those cast from CPU-built lists (what `--lists gl` will do).
// The lists go through the CPU caster's own frame loop (core/frame/cast_tiles.h: cast_frame with a
// SegmentListView, the loop InCoreRenderer runs), so the comparison is the renderer's, not a copy of it.
#include <gtest/gtest.h>

#include <cstring>

#include "core/scene/generate.h"
#include "core/occupancy/block_metadata.h"
#include "core/frame/cast_tiles.h"
#include "core/frame/in_core_renderer.h"
#include "core/occupancy/culling.h"
#include "core/lists/segment_list_builder.h"
#include "gl/gl_segment_list_builder.h"
#include "tests/gl/gl_test_util.h"

namespace sl {
namespace {

struct Picture {
  std::vector<vec4> rgba;
  std::vector<float> samples;
  std::uint64_t total_samples = 0;
  std::size_t covered = 0;  // pixels with any opacity
};

// lists == nullptr: no skipping (every grid sample from volume entry to exit).
Picture cast(const Volume& volume, const TransferFunction& tf, const Camera& cam, int w, int h,
             const SegmentListBuffer* lists) {
  Scene scene;
  scene.volume = &volume;
  scene.tf = &tf;
  scene.camera = cam;
  RenderSettings settings;
  settings.width = w;
  settings.height = h;
  LabelSet label_storage;
  DenseGrid<std::uint8_t> grid;
  grid.data = volume.as<std::uint8_t>();
  grid.dims = volume.dims();
  grid.inv_spacing = 1.0f / volume.desc().spacing;
  const RayCaster<DenseSampler<std::uint8_t, std::uint8_t>> caster{make_cast_params(scene, settings, label_storage),
                                                                   {grid, {}}};
  SkipInputs skip;
  if (lists) {
    skip.method = SkipMethod::SparseLeap;
    skip.lists = lists->view();
  }
  Frame frame;
  frame.image = Image(w, h);
  cast_frame(caster, make_ray_generator(cam, w, h), Box3{vec3(0.0f), volume.desc().extent()}, skip, frame);
  Picture pic;
  pic.rgba = frame.image.rgba;
  pic.samples = frame.image.channel("samples");
  pic.total_samples = frame.stats.samples;
  for (const vec4& c : pic.rgba) pic.covered += c.w > 0.0f ? 1 : 0;
  return pic;
}

void expect_identical(const Picture& a, const Picture& b) {
  ASSERT_EQ(a.rgba.size(), b.rgba.size());
  std::size_t differing = 0;
  for (std::size_t i = 0; i < a.rgba.size(); ++i) {
    differing += std::memcmp(&a.rgba[i], &b.rgba[i], sizeof(vec4)) != 0 || a.samples[i] != b.samples[i];
  }
  EXPECT_EQ(differing, 0u);
  EXPECT_EQ(a.total_samples, b.total_samples);
}

struct Scenario {
  GeneratedVolume data;
  TransferFunction tf = default_transfer_function(0.0f, 255.0f);
  OccupancyTree tree;
  OccupancyGeometry geometry;
};

// Neurites on an odd grid, culled against the transfer function (conservative, DESIGN.md "Occupancy histogram tree").
const Scenario& culled_neurites() {
  static const Scenario s = [] {
    Scenario r;
    r.data = generate_volume("neurites", ivec3(61, 47, 53), 3);
    const BlockGrid grid = make_block_grid(r.data.intensity.dims(), r.data.intensity.desc().spacing, 4);
    const BlockMetadataTable meta = compute_all_block_metadata(grid, r.data.intensity.view(), nullptr);
    CullParams cull;
    cull.tf = &r.tf;
    r.tree = OccupancyTree::from_block_classes(grid, classify_blocks(meta, cull));
    r.geometry = build_occupancy_geometry(r.tree);
    return r;
  }();
  return s;
}

void compare_images(GlContext& ctx, const OccupancyTree& tree, const OccupancyGeometry& geometry, const Volume& volume,
                    const TransferFunction& tf, const Camera& cam, int w, int h, bool culling_is_conservative) {
  const RayGenerator gen = make_ray_generator(cam, w, h);
  const auto order = build_visibility_order(tree, geometry, view_point(gen));
  SegmentListBuffer cpu, gl;
  build_segment_lists(geometry, order, gen, cpu);
  GlSegmentListBuilder builder(ctx);
  builder.build_segment_lists(geometry, order, gen, gl);
  test::expect_same_lists(ctx, gl, cpu);
  const Picture from_cpu = cast(volume, tf, cam, w, h, &cpu);
  const Picture from_gl = cast(volume, tf, cam, w, h, &gl);
  expect_identical(from_gl, from_cpu);
  EXPECT_GT(from_gl.covered, std::size_t(w) * h / 50) << "the view shows little of the data";
  if (culling_is_conservative) {
    // Skipping only what the culling proved empty leaves the image unchanged (DESIGN.md "Ray casting"), with
    // fewer samples: checks that the walk above is the caster's.
    const Picture full = cast(volume, tf, cam, w, h, nullptr);
    ASSERT_EQ(full.rgba.size(), from_gl.rgba.size());
    std::size_t differing = 0;
    for (std::size_t i = 0; i < full.rgba.size(); ++i) {
      differing += std::memcmp(&full.rgba[i], &from_gl.rgba[i], sizeof(vec4)) != 0;
    }
    EXPECT_EQ(differing, 0u);
    EXPECT_LT(from_gl.total_samples, full.total_samples);
  }
}

TEST(GlListsImage, CulledNeuritesRenderIdenticallyFromGlAndCpuLists) {
  SL_REQUIRE_GL(ctx);
  const Scenario& s = culled_neurites();
  std::printf("[ GL       ] %zu boxes\n", s.geometry.boxes.size());
  const vec3 c = 0.5f * s.data.intensity.desc().extent();
  compare_images(*ctx, s.tree, s.geometry, s.data.intensity, s.tf, test::gl_perspective(vec3(90.0f, 60.0f, 120.0f), c), 61, 47, true);
  compare_images(*ctx, s.tree, s.geometry, s.data.intensity, s.tf,
                 test::gl_perspective(vec3(25.0f, 20.0f, 30.0f), vec3(50.0f, 25.0f, 5.0f), 90.0f), 128, 96, true);
  compare_images(*ctx, s.tree, s.geometry, s.data.intensity, s.tf,
                 test::gl_orthographic(vec3(-40.0f, 30.0f, 100.0f), c, 90.0f), 61, 47, true);
}

TEST(GlListsImage, RandomOccupancyRendersIdenticallyFromGlAndCpuLists) {
  SL_REQUIRE_GL(ctx);
  // Random classes are not conservative for the data, so skipping changes the image: what matters
  // is that both builders' lists change it identically.
  const Scenario& s = culled_neurites();
  const test::GlFixture f = test::random_gl_fixture(8, s.data.intensity.dims(), vec3(1.0f), 4, 300);
  const vec3 c = 0.5f * s.data.intensity.desc().extent();
  compare_images(*ctx, f.tree, f.geometry, s.data.intensity, s.tf, test::gl_perspective(vec3(-70.0f, 50.0f, 110.0f), c), 128, 96, false);
}

}  // namespace
}  // namespace sl
