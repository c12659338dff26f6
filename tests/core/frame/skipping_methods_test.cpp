// The four skipping methods take the same samples on the same grid, so with conservative culling they
// must produce the same image (DESIGN.md "Ray casting"): none, bbox, octree and sparseleap, on odd dims, for
// several transfer functions, label subsets, modes and cameras.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "core/scene/generate.h"
#include "core/occupancy/block_metadata.h"
#include "core/frame/in_core_renderer.h"
#include "core/scene/labels.h"

namespace sl {
namespace {

constexpr SkipMethod kMethods[] = {SkipMethod::None, SkipMethod::BBox, SkipMethod::Octree, SkipMethod::SparseLeap};

struct Case {
  std::string name;
  RenderMode mode = RenderMode::Dvr;
  int tf = 0;             // which transfer function
  std::string enable{};   // label subset ("" = no mask)
  int camera = 0;         // 0 default, 1 inside, 2 orthographic, 3 grazing along a face
  int block = 16;
  bool ert = false;
  IsoMethod iso_method = IsoMethod::Exact;  // iso mode: exact roots (the default) or sampled bisection
  bool shade = false;                       // dvr, labels: Blinn–Phong (--shade)
  Filter filter = Filter::Linear;           // reconstruction (--filter)
};

class SkippingMethods : public ::testing::TestWithParam<Case> {
 protected:
  static void SetUpTestSuite() {
    data_ = new GeneratedVolume(generate_volume("neurites", ivec3(97, 131, 73), 7));
  }
  static void TearDownTestSuite() {
    delete data_;
    data_ = nullptr;
  }
  static GeneratedVolume* data_;
};
GeneratedVolume* SkippingMethods::data_ = nullptr;

TransferFunction make_tf(int which) {
  switch (which) {
    case 0: return default_transfer_function(0, 255);
    case 1:  // narrow band: most blocks cull
      return TransferFunction({{0, {0, 0, 0, 0}}, {180, {0, 0, 0, 0}}, {200, {0.2f, 0.7f, 1, 0.6f}}, {220, {0, 0, 0, 0}}});
    default:  // everything above 0 visible: almost nothing culls
      return TransferFunction({{0, {0, 0, 0, 0}}, {1, {1, 1, 1, 0.02f}}, {255, {1, 0.5f, 0.2f, 0.9f}}});
  }
}

Camera make_camera(int which, const vec3& ext) {
  Camera c = default_camera(ext);
  switch (which) {
    case 1:  // inside the volume, looking across it
      c.eye = vec3(0.3f, 0.55f, 0.4f) * ext;
      c.center = vec3(0.9f, 0.4f, 0.7f) * ext;
      c.fov_deg = 70.0f;
      break;
    case 2:
      c.projection = Projection::Orthographic;
      c.height = glm::length(ext);
      break;
    case 3:  // view axis exactly on a block plane (x = 64, y = 64): rays lie in split planes
      c.eye = vec3(64.0f, 64.0f, ext.z + 60.0f);
      c.center = vec3(64.0f, 64.0f, 0.0f);
      c.fov_deg = 50.0f;
      break;
    default: break;
  }
  return c;
}

TEST_P(SkippingMethods, ProduceIdenticalImages) {
  const Case& k = GetParam();
  const TransferFunction tf = make_tf(k.tf);
  std::optional<LabelSet> enabled;
  if (!k.enable.empty()) enabled = parse_enable_spec(k.enable, data_->label_count);
  Scene scene{&data_->intensity, &data_->labels, &tf, enabled ? &*enabled : nullptr,
              make_camera(k.camera, data_->intensity.desc().extent())};
  RenderSettings s;
  s.width = 67;  // odd sizes: pixel centres fall on block planes for the centred cameras
  s.height = 53;
  s.mode = k.mode;
  s.iso = 150.0f;
  s.iso_method = k.iso_method;
  s.lighting.enabled = k.shade;
  s.filter = k.filter;
  s.block = k.block;
  s.ert = k.ert;
  s.fine_cell = 0;  // the four methods as the paper has them; the fine grid is checked below
  std::vector<Frame> frames;
  for (SkipMethod m : kMethods) {
    s.method = m;
    InCoreRenderer r;
    frames.push_back(r.render(scene, s));
  }
  // SparseLeap with the fine occupancy grid inside its segments (core/occupancy/fine_occupancy.h).
  for (int cell : {4, 8, kFineCellAuto}) {
    s.method = SkipMethod::SparseLeap;
    s.fine_cell = cell;
    InCoreRenderer r;
    const Frame f = r.render(scene, s);
    ASSERT_EQ(f.image.rgba.size(), frames[0].image.rgba.size());
    EXPECT_EQ(std::memcmp(f.image.rgba.data(), frames[3].image.rgba.data(), f.image.rgba.size() * sizeof(vec4)), 0)
        << "fine cells of " << cell << " voxels change the image";
    EXPECT_LE(f.stats.samples, frames[3].stats.samples);
  }
  const Frame& ref = frames[0];
  float visible = 0.0f;
  for (const vec4& c : ref.image.rgba) visible += c.w;
  EXPECT_GT(visible, 0.5f) << "scene shows nothing: the comparison would be vacuous";
  for (std::size_t m = 1; m < frames.size(); ++m) {
    float max_diff = 0.0f;
    for (std::size_t i = 0; i < ref.image.rgba.size(); ++i) {
      const vec4 d = glm::abs(frames[m].image.rgba[i] - ref.image.rgba[i]);
      max_diff = std::max({max_diff, d.x, d.y, d.z, d.w});
    }
    EXPECT_LE(max_diff, 1e-5f) << to_string(kMethods[m]) << " differs from none";
    // Iso pays for the walk's restart at each span: 8 cell corners (64 control points for the cubic).
    const std::uint64_t restart = k.filter == Filter::Linear ? 64 : 512;
    EXPECT_LE(frames[m].stats.samples, ref.stats.samples + (k.mode == RenderMode::Iso ? ref.stats.rays * restart : 0))
        << to_string(kMethods[m]);
  }
  // SparseLeap never takes more samples than no skipping (iso adds at most two per segment).
  if (k.mode != RenderMode::Iso) {
    EXPECT_LE(frames[3].stats.samples, ref.stats.samples);
    // Same non-empty spans as the octree, except for rays lying exactly in split planes, where each
    // method may take either (conservative) side.
    if (k.camera != 3) {
      EXPECT_EQ(frames[3].stats.samples, frames[2].stats.samples);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(
    Neurites97x131x73, SkippingMethods,
    ::testing::Values(Case{"dvr_default", RenderMode::Dvr, 0, ""}, Case{"dvr_narrow_band", RenderMode::Dvr, 1, ""},
                      Case{"dvr_dense_tf", RenderMode::Dvr, 2, ""},
                      Case{"dvr_sparse_labels", RenderMode::Dvr, 0, "fraction:0.1:3"},
                      Case{"dvr_label_list", RenderMode::Dvr, 2, "1-12,17,25-27"},
                      Case{"labels_all", RenderMode::Labels, 0, ""},
                      Case{"labels_fraction", RenderMode::Labels, 2, "fraction:0.3:1"},
                      Case{"mip_labels", RenderMode::Mip, 0, "fraction:0.2:5"},
                      Case{"iso", RenderMode::Iso, 0, ""},
                      Case{"iso_labels", RenderMode::Iso, 0, "fraction:0.5:2"},
                      Case{"camera_inside", RenderMode::Dvr, 0, "", 1},
                      Case{"orthographic", RenderMode::Dvr, 1, "", 2},
                      Case{"rays_in_block_planes", RenderMode::Dvr, 0, "", 3},
                      Case{"block4", RenderMode::Dvr, 0, "fraction:0.1:3", 0, 4},
                      Case{"block32_ert", RenderMode::Dvr, 2, "", 0, 32, true},
                      Case{"block8_inside_iso", RenderMode::Iso, 0, "", 1, 8},
                      Case{"iso_sampled", RenderMode::Iso, 0, "", 0, 16, false, IsoMethod::Sampled},
                      Case{"iso_labels_sampled", RenderMode::Iso, 0, "fraction:0.5:2", 0, 16, false, IsoMethod::Sampled},
                      Case{"block8_inside_iso_sampled", RenderMode::Iso, 0, "", 1, 8, false, IsoMethod::Sampled},
                      Case{"iso_orthographic", RenderMode::Iso, 0, "", 2},
                      Case{"iso_rays_in_block_planes", RenderMode::Iso, 0, "", 3},
                      Case{"block4_iso_labels", RenderMode::Iso, 0, "fraction:0.3:4", 0, 4},
                      Case{"dvr_shaded", RenderMode::Dvr, 0, "", 0, 16, false, IsoMethod::Exact, true},
                      Case{"dvr_shaded_narrow_labels", RenderMode::Dvr, 1, "fraction:0.3:1", 0, 16, false,
                           IsoMethod::Exact, true},
                      Case{"dvr_shaded_inside_ert", RenderMode::Dvr, 2, "", 1, 8, true, IsoMethod::Exact, true},
                      // B-spline reconstruction (culling metadata widened to the filter's footprint).
                      Case{"dvr_cubic_narrow_band", RenderMode::Dvr, 1, "", 0, 16, false, IsoMethod::Exact, false,
                           Filter::Cubic},
                      Case{"dvr_quadratic_labels", RenderMode::Dvr, 0, "fraction:0.1:3", 0, 16, false,
                           IsoMethod::Exact, false, Filter::Quadratic},
                      Case{"dvr_cubic_shaded_block4", RenderMode::Dvr, 0, "", 0, 4, false, IsoMethod::Exact, true,
                           Filter::Cubic},
                      Case{"mip_cubic_labels", RenderMode::Mip, 0, "fraction:0.2:5", 0, 16, false, IsoMethod::Exact,
                           false, Filter::Cubic},
                      Case{"iso_cubic", RenderMode::Iso, 0, "", 0, 16, false, IsoMethod::Exact, false, Filter::Cubic},
                      Case{"iso_quadratic_inside", RenderMode::Iso, 0, "", 1, 8, false, IsoMethod::Exact, false,
                           Filter::Quadratic},
                      Case{"iso_cubic_labels_sampled", RenderMode::Iso, 0, "fraction:0.5:2", 0, 16, false,
                           IsoMethod::Sampled, false, Filter::Cubic},
                      // Lit labels: each label shaded by the gradient of its mask.
                      Case{"labels_shaded", RenderMode::Labels, 0, "", 0, 16, false, IsoMethod::Exact, true},
                      Case{"labels_shaded_cubic_fraction", RenderMode::Labels, 2, "fraction:0.3:1", 1, 8, false,
                           IsoMethod::Exact, true, Filter::Cubic}),
    [](const ::testing::TestParamInfo<Case>& i) { return i.param.name; });

TEST(SkippingReuse, TransferFunctionAndLabelChangesReuseMetadata) {
  GeneratedVolume g = generate_volume("neurites", ivec3(64, 48, 40), 2);
  TransferFunction a = make_tf(0), b = make_tf(1);
  LabelSet some = parse_enable_spec("fraction:0.3:1", g.label_count);
  Scene scene{&g.intensity, &g.labels, &a, nullptr, default_camera(g.intensity.desc().extent())};
  RenderSettings s;
  s.width = s.height = 32;
  InCoreRenderer r;
  const Frame first = r.render(scene, s);
  EXPECT_GT(first.stats.metadata_blocks, 0u);
  const std::uint64_t computed = block_metadata_computations();
  scene.tf = &b;  // transfer-function change
  const Frame second = r.render(scene, s);
  scene.enabled = &some;  // label change
  const Frame third = r.render(scene, s);
  EXPECT_EQ(block_metadata_computations(), computed) << "metadata must not be recomputed";
  EXPECT_NE(first.stats.samples, second.stats.samples);  // the re-cull took effect
  EXPECT_NE(second.stats.samples, third.stats.samples);
}

TEST(SkippingReuse, ListsAreReusedWhileTheViewIsUnchanged) {
  GeneratedVolume g = generate_volume("neurites", ivec3(48, 48, 48), 4);
  TransferFunction tf = make_tf(0);
  Scene scene{&g.intensity, &g.labels, &tf, nullptr, default_camera(g.intensity.desc().extent())};
  RenderSettings s;
  s.width = s.height = 40;
  InCoreRenderer r;
  const Frame first = r.render(scene, s);
  EXPECT_GT(first.stats.events, 0u);
  s.step = 0.25f;  // step changes: lists stay
  const Frame second = r.render(scene, s);
  EXPECT_EQ(second.stats.time_ms.lists, 0.0);
  EXPECT_EQ(second.stats.events, first.stats.events);
  scene.camera.eye += vec3(3.0f, 0.0f, 0.0f);  // the view moves: lists are rebuilt
  const Frame third = r.render(scene, s);
  EXPECT_GT(third.stats.time_ms.lists, 0.0);
}

}  // namespace
}  // namespace sl
