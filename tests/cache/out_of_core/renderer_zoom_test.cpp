// Conservative culling at every level (DESIGN.md "Virtual memory": "metadata is a min/max pyramid"): a
// far view of thin structures culls from coarse levels, whose means of a 1-voxel tube are dim; the
// same renderer zoomed in must still find every tube, converging to the in-core image of the close
// view. Before the bounds pyramid, coarse blocks were culled EMPTY from the means and stayed EMPTY.
// Sources with bounds (in memory) cull coarse levels for good; sources without (a stored pyramid of
// means: OME-Zarr stores) cull provisionally, opened when a finer level is wanted there.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>

#include "cache/formats/ingest.h"
#include "cache/formats/nrrd/nrrd.h"
#include "cache/formats/zarr/source.h"
#include "cache/out_of_core/renderer.h"
#include "core/frame/in_core_renderer.h"
#include "tests/test_util.h"

namespace sl {
namespace {

constexpr int kEdge = 128;

// 1-voxel tubes: straight segments between fixed points, rasterised a quarter voxel apart, intensity
// 255 and labels 1..n; the background is 0. At level 1 a tube covers at most a quarter of a 2³ cell
// (mean <= 64), at level 2 a sixteenth: below the transfer function's opaque range.
struct Tubes {
  std::shared_ptr<const Volume> volume, labels;
  std::uint32_t count = 0;
};

const Tubes& tubes() {
  static const Tubes t = [] {
    VolumeDesc d;
    d.dims = ivec3(kEdge);
    d.type = VoxelType::U8;
    Volume v(d, "tubes");
    d.type = VoxelType::U16;
    Volume l(d, "tube labels");
    const vec3 ends[][2] = {{{5.5f, 20.5f, 30.5f}, {120.5f, 100.5f, 90.5f}},
                            {{64.5f, 3.5f, 64.5f}, {64.5f, 124.5f, 64.5f}},
                            {{10.5f, 110.5f, 12.5f}, {115.5f, 15.5f, 118.5f}},
                            {{30.5f, 64.5f, 4.5f}, {40.5f, 70.5f, 123.5f}},
                            {{100.5f, 30.5f, 20.5f}, {20.5f, 90.5f, 110.5f}}};
    Tubes out;
    for (const auto& e : ends) {
      ++out.count;
      const int n = int(std::ceil(glm::distance(e[0], e[1]) * 4.0f));
      for (int k = 0; k <= n; ++k) {
        const ivec3 p = ivec3(glm::floor(glm::mix(e[0], e[1], float(k) / float(n))));
        v.set(p.x, p.y, p.z, 255.0f);
        l.set(p.x, p.y, p.z, float(out.count));
      }
    }
    out.volume = std::make_shared<const Volume>(std::move(v));
    out.labels = std::make_shared<const Volume>(std::move(l));
    return out;
  }();
  return t;
}

// Transparent below 160: only level-0 samples near a tube's centre line are visible.
TransferFunction thin_tf() {
  return TransferFunction({{0.0f, vec4(0.0f)}, {160.0f, vec4(0.0f)}, {255.0f, vec4(1.0f, 0.8f, 0.5f, 1.0f)}});
}

Camera view_from(float distance) {
  Camera c;
  c.center = vec3(float(kEdge) * 0.5f);
  c.eye = c.center + glm::normalize(vec3(0.6f, 0.5f, 1.0f)) * distance;
  return c;
}

RenderSettings settings() {
  RenderSettings s;
  s.width = 128;
  s.height = 96;
  s.block = 8;
  return s;
}

// Renders until converged, letting the loader finish between frames; the last frame.
Frame converge(OutOfCoreRenderer& r, const OutOfCoreScene& scene, const RenderSettings& s) {
  Frame f;
  for (int i = 0; i < 40; ++i) {
    f = r.render(scene, s);
    if (r.converged()) return f;
    r.wait_for_loads();
  }
  ADD_FAILURE() << "did not converge in 40 frames";
  return f;
}

float alpha_sum(const Frame& f) {
  float a = 0.0f;
  for (const vec4& c : f.image.rgba) a += c.w;
  return a;
}

OutOfCoreSettings roomy() {
  OutOfCoreSettings os;
  os.cache_mb = 64;
  os.brick = 16;
  return os;
}

void expect_far_then_close_equals_in_core(const std::shared_ptr<const VolumeSource>& source, const Tubes& t,
                                          const LabelSet* enabled) {
  const TransferFunction tf = thin_tf();
  const RenderSettings s = settings();
  OutOfCoreRenderer r(source, roomy(), s.block);
  // Far: about 10 pixels across the volume, every sample at level >= 2.
  const Frame far = converge(r, OutOfCoreScene{&tf, enabled, view_from(1600.0f)}, s);
  EXPECT_GT(r.metadata_blocks(), 0u);
  EXPECT_EQ(far.stats.cache.completeness, 1.0);
  // Close: every sample at level 0.
  const Camera close = view_from(170.0f);
  const Frame near = converge(r, OutOfCoreScene{&tf, enabled, close}, s);
  EXPECT_EQ(near.stats.cache.completeness, 1.0);
  const Frame in_core =
      InCoreRenderer().render(Scene{t.volume.get(), t.labels.get(), &tf, enabled, close}, s);
  // Zoomed in, the tree refines to level 0 where the rays now sample (the close view's own metadata),
  // so skipping is as good as for a renderer that saw only the close view.
  OutOfCoreRenderer fresh(source, roomy(), s.block);
  const Frame direct = converge(fresh, OutOfCoreScene{&tf, enabled, close}, s);
  EXPECT_TRUE(direct.image.rgba == in_core.image.rgba);
  EXPECT_LE(double(near.stats.samples), 1.05 * double(direct.stats.samples))
      << "after the far view: " << near.stats.samples << " samples, close view alone: " << direct.stats.samples;
  EXPECT_GT(alpha_sum(in_core), 20.0f) << "the close view must show the tubes";
  EXPECT_TRUE(near.image.rgba == in_core.image.rgba)
      << "zoomed in after a far view, the out-of-core image lost structure (alpha " << alpha_sum(near)
      << ", in core " << alpha_sum(in_core) << ")";
}

TEST(OutOfCoreZoom, ThinTubesSurviveCoarseCullingWhenZoomingIn) {
  const Tubes& t = tubes();
  expect_far_then_close_equals_in_core(std::make_shared<MemoryVolumeSource>(t.volume, t.labels, "tubes"), t, nullptr);
}

TEST(OutOfCoreZoom, ThinTubesSurviveWithLabelCulling) {
  const Tubes& t = tubes();
  const LabelSet enabled = parse_enable_spec("1,3,5", t.count);
  expect_far_then_close_equals_in_core(std::make_shared<MemoryVolumeSource>(t.volume, t.labels, "tubes"), t,
                                       &enabled);
}

// A source whose coarse levels are a stored pyramid of means and which cannot bound them (what a
// foreign store is): its coarse EMPTY is provisional.
class MeansOnlySource final : public VolumeSource {
 public:
  explicit MeansOnlySource(std::shared_ptr<const VolumeSource> s) : s_(std::move(s)) {}
  const VolumeDesc& desc() const override { return s_->desc(); }
  bool has_labels() const override { return s_->has_labels(); }
  VoxelType label_type() const override { return s_->label_type(); }
  const std::string& name() const override { return s_->name(); }
  void read_brick(const BrickLayout& layout, BrickId id, std::span<std::byte> out_intensity,
                  std::span<std::byte> out_labels) const override {
    s_->read_brick(layout, id, out_intensity, out_labels);
  }

 private:
  std::shared_ptr<const VolumeSource> s_;
};

TEST(OutOfCoreZoom, SourcesWithoutBoundsOpenProvisionalEmptyWhereAFinerLevelIsWanted) {
  const Tubes& t = tubes();
  const auto memory = std::make_shared<MemoryVolumeSource>(t.volume, t.labels, "tubes");
  const LabelSet enabled = parse_enable_spec("1,3,5", t.count);
  for (const LabelSet* e : {static_cast<const LabelSet*>(nullptr), &enabled}) {
    SCOPED_TRACE(e ? "labels 1,3,5" : "all labels");
    expect_far_then_close_equals_in_core(std::make_shared<MeansOnlySource>(memory), t, e);
  }
}

// The same through an OME-Zarr store written by ingest (its levels are means).
TEST(OutOfCoreZoom, ZarrStoreZoomsInWithoutLosingTubes) {
  const Tubes& t = tubes();
  const std::filesystem::path dir = test::scratch_dir();
  write_nrrd((dir / "tubes.nrrd").string(), *t.volume);
  write_nrrd((dir / "labels.nrrd").string(), *t.labels);
  IngestOptions o;
  o.chunk = 32;
  o.labels = (dir / "labels.nrrd").string();
  ingest((dir / "tubes.nrrd").string(), (dir / "tubes.zarr").string(), o);
  const auto zarr = std::make_shared<ZarrVolumeSource>((dir / "tubes.zarr").string());
  ASSERT_TRUE(zarr->has_labels());
  expect_far_then_close_equals_in_core(zarr, t, nullptr);
}

}  // namespace
}  // namespace sl
