// A converged out-of-core frame is the in-core frame, byte for byte: for every skipping method the
// out-of-core renderer has (sparseleap, none) against the in-core sparseleap, in every mode (dvr,
// dvr lit, dvr with early termination, dvr without the SIMD batch, mip, iso, labels), on the built-in
// generated sets, level 0 pinned, in a cache smaller than the volume: a view of one corner converges
// first, then a view of the opposite corner, whose bricks evict the first one's. (A cache smaller
// than one view's working set at a pinned level does not converge to the exact image yet: that needs
// rays that suspend and resume over several passes.)
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "cache/brick.h"
#include "cache/out_of_core/renderer.h"
#include "core/frame/in_core_renderer.h"
#include "core/scene/generate.h"
#include "core/scene/labels.h"
#include "core/scene/transfer_function.h"

namespace sl {
namespace {

struct Data {
  std::string kind;
  std::shared_ptr<const Volume> volume, labels;
  std::uint32_t label_count = 0;
  float iso = 128;
  TransferFunction tf = default_transfer_function(0, 255);
  std::string enable = "fraction:0.35:2";  // the labels masked in (dvr, mip, iso) or shown (labels mode)
};

const Data& data(const std::string& kind) {
  static std::vector<std::unique_ptr<Data>> all;
  for (const auto& d : all)
    if (d->kind == kind) return *d;
  auto d = std::make_unique<Data>();
  d->kind = kind;
  const ivec3 dims(160, 144, 128);  // 2.8 MiB of u8 (+ 5.6 MiB of u16 labels), 11.3 MiB of f32
  GeneratedVolume g = generate_volume(kind, dims, 7);
  d->label_count = g.label_count;
  d->volume = std::make_shared<const Volume>(std::move(g.intensity));
  if (!g.labels.empty()) d->labels = std::make_shared<const Volume>(std::move(g.labels));
  if (kind == "neurites") {
    d->iso = 140;
  } else if (kind == "blobs") {
    d->iso = 100;
  } else if (kind == "organs") {
    d->iso = 150;       // the spine (192-240) in the body (72-90)
    d->enable = "2-3";  // body and spine (skin and heart hide them or show little)
  } else if (kind == "sphere") {
    // A shell of radius 44-60: the inside and the outside are culled.
    d->tf = TransferFunction({{42.0f, vec4(0.0f)},
                              {44.0f, {0.9f, 0.5f, 0.2f, 0.3f}},
                              {56.0f, {1.0f, 0.9f, 0.6f, 0.6f}},
                              {60.0f, vec4(0.0f)}});
    d->iso = 50;
  }
  all.push_back(std::move(d));
  return *all.back();
}

enum class Mode { Dvr, DvrLit, DvrErt, DvrScalar, Mip, Iso, Labels };

const char* name(Mode m) {
  switch (m) {
    case Mode::Dvr: return "dvr";
    case Mode::DvrLit: return "dvr_lit";
    case Mode::DvrErt: return "dvr_ert";
    case Mode::DvrScalar: return "dvr_scalar";
    case Mode::Mip: return "mip";
    case Mode::Iso: return "iso";
    case Mode::Labels: return "labels";
  }
  return "?";
}

RenderSettings settings(Mode m, const Data& d) {
  RenderSettings s;
  s.width = 80;
  s.height = 64;
  s.block = 8;
  switch (m) {
    case Mode::Dvr: break;
    case Mode::DvrLit: s.lighting.enabled = true; break;
    case Mode::DvrErt: s.ert = true; break;
    case Mode::DvrScalar: s.simd = false; break;
    case Mode::Mip: s.mode = RenderMode::Mip; break;
    case Mode::Iso:
      s.mode = RenderMode::Iso;
      s.iso = d.iso;
      break;
    case Mode::Labels: s.mode = RenderMode::Labels; break;
  }
  return s;
}

// A view of the corner of the volume at `at` (a share of the extent), from outside beyond that corner:
// it sees about half the volume, so its bricks fit in a cache that the whole volume does not.
Camera corner_view(const Data& d, vec3 at, vec3 from) {
  const vec3 extent = d.volume->desc().extent();
  Camera c;
  c.center = at * extent;
  c.eye = c.center + glm::normalize(from) * (0.6f * glm::length(extent));
  c.up = vec3(0, 0, 1);
  c.fov_deg = 24.0f;
  return c;
}

// The opposite corner from the test view's.
Camera opposite_view(const Data& d) { return corner_view(d, vec3(0.68f, 0.64f, 0.6f), vec3(0.6f, 0.65f, 0.5f)); }

struct Case {
  std::string kind;
  Mode mode;
};

// The test view (one corner of the volume) and its in-core frame.
struct Reference {
  const Data& d;
  LabelSet enabled;
  const LabelSet* en = nullptr;
  RenderSettings s;
  Camera cam;
  Frame in_core;

  explicit Reference(const Case& c) : d(data(c.kind)) {
    if (d.labels) {
      enabled = parse_enable_spec(d.enable, d.label_count);
      en = &enabled;
    }
    s = settings(c.mode, d);
    cam = corner_view(d, vec3(0.32f, 0.36f, 0.4f), vec3(-0.55f, -0.7f, -0.45f));
    in_core = InCoreRenderer().render(Scene{d.volume.get(), d.labels.get(), &d.tf, en, cam}, s);
  }
  OutOfCoreScene scene(const Camera& view) const { return OutOfCoreScene{&d.tf, en, view}; }
};

// Renders `view` until converged; the frames' evictions are added to `evictions`.
Frame converge(OutOfCoreRenderer& r, const OutOfCoreScene& scene, const RenderSettings& s, int max_frames,
               std::uint64_t* evictions = nullptr) {
  Frame f;
  for (int i = 0; i < max_frames; ++i) {
    f = r.render(scene, s);
    if (evictions) *evictions += f.stats.cache.evictions;
    if (r.converged()) return f;
    r.wait_for_loads();
  }
  ADD_FAILURE() << "did not converge in " << max_frames << " frames";
  return f;
}

// Level 0 pinned, bricks of 16, a cache of `cache_mb`.
OutOfCoreSettings level_zero(std::size_t cache_mb) {
  OutOfCoreSettings os;
  os.brick = 16;
  os.lod = 0;
  os.cache_mb = cache_mb;
  return os;
}

RenderSettings with_method(RenderSettings s, SkipMethod m) {
  s.method = m;
  return s;
}

// The view's working set at level 0: the bricks its converged frame uses, with their aprons.
double working_set_mb(const std::shared_ptr<const VolumeSource>& source, const Reference& ref, const RenderSettings& s) {
  const OutOfCoreSettings os = level_zero(64);  // the whole volume
  OutOfCoreRenderer whole(source, os, s.block);
  const int stored = os.brick + 2 * kBrickApron;
  const Data& d = ref.d;
  const double voxel_bytes =
      double(voxel_size(d.volume->desc().type)) + (d.labels ? double(voxel_size(d.labels->desc().type)) : 0.0);
  return double(converge(whole, ref.scene(ref.cam), s, 80).stats.cache.hits) * stored * stored * stored *
         voxel_bytes / (1 << 20);
}

void expect_same_image(const Frame& f, const Frame& in_core) {
  ASSERT_EQ(f.image.rgba.size(), in_core.image.rgba.size());
  std::size_t differing = 0, first = 0;
  float worst = 0;
  for (std::size_t i = 0; i < f.image.rgba.size(); ++i)
    if (f.image.rgba[i] != in_core.image.rgba[i]) {
      if (differing++ == 0) first = i;
      const vec4 e = glm::abs(f.image.rgba[i] - in_core.image.rgba[i]);
      worst = std::max(worst, std::max(std::max(e.x, e.y), std::max(e.z, e.w)));
    }
  EXPECT_EQ(differing, 0u) << "pixels differing from the in-core frame; the first at ("
                           << first % std::size_t(f.image.width) << ", " << first / std::size_t(f.image.width)
                           << "), largest difference " << worst;
  float alpha = 0;
  for (const vec4& p : in_core.image.rgba) alpha += p.w;
  EXPECT_GT(alpha, 5.0f) << "the comparison must not be of two nearly empty images";
}

const char* name(SkipMethod m) { return m == SkipMethod::None ? "out of core: none" : "out of core: sparseleap"; }

class OutOfCoreEqualsInCore : public ::testing::TestWithParam<Case> {};

TEST_P(OutOfCoreEqualsInCore, ConvergedFrameIsTheInCoreFrameForEveryMethod) {
  const Reference ref(GetParam());
  const Data& d = ref.d;
  // Seen first, so that the test view's bricks replace some of theirs in the cache: the opposite
  // corner, then the whole volume.
  const Camera others[] = {opposite_view(d), default_camera(d.volume->desc().extent())};
  auto source = std::make_shared<MemoryVolumeSource>(d.volume, d.labels, GetParam().kind);
  for (SkipMethod method : {SkipMethod::SparseLeap, SkipMethod::None}) {
    SCOPED_TRACE(name(method));
    const RenderSettings so = with_method(ref.s, method);
    // The view's working set and a margin: less than all three views need (the cache evicts), more
    // than this one does (one pass).
    const OutOfCoreSettings os = level_zero(std::size_t(std::ceil(1.05 * working_set_mb(source, ref, so))));
    OutOfCoreRenderer r(source, os, so.block);
    std::uint64_t evictions = 0;
    for (const Camera& other : others) converge(r, ref.scene(other), so, 80, &evictions);
    const Frame f = converge(r, ref.scene(ref.cam), so, 80, &evictions);
    EXPECT_GT(evictions, 0u) << "the cache must not hold all three views' bricks";
    EXPECT_EQ(f.stats.cache.completeness, 1.0);
    EXPECT_EQ(f.stats.cache.depth_passes, 0) << "the view fits: one pass";
    EXPECT_LE(f.stats.cache.resident_mb, double(os.cache_mb));
    expect_same_image(f, ref.in_core);
  }
}

// A pinned level whose working set is twice the cache: the frames settle short of complete, then go
// on in depth passes (cache/out_of_core/depth_passes.h) to the exact image of the level.
class PinnedLevelInDepthPasses : public ::testing::TestWithParam<Case> {};

TEST_P(PinnedLevelInDepthPasses, HalfTheWorkingSetConvergesToTheInCoreFrame) {
  const Reference ref(GetParam());
  const Data& d = ref.d;
  auto source = std::make_shared<MemoryVolumeSource>(d.volume, d.labels, GetParam().kind);
  for (SkipMethod method : {SkipMethod::SparseLeap, SkipMethod::None}) {
    SCOPED_TRACE(name(method));
    RenderSettings so = with_method(ref.s, method);
    double working_set = working_set_mb(source, ref, so);
    if (working_set < 2.0) {
      // Tight boxes leave the thin sets a working set too small to halve in whole MB: whole boxes then
      // (the denser sets run the passes with tight boxes).
      so.tight_boxes = false;
      working_set = working_set_mb(source, ref, so);
    }
    const OutOfCoreSettings os = level_zero(std::max<std::size_t>(1, std::size_t(0.5 * working_set)));
    OutOfCoreRenderer r(source, os, so.block);
    const Frame f = converge(r, ref.scene(ref.cam), so, 400);
    EXPECT_EQ(f.stats.cache.completeness, 1.0);
    EXPECT_GE(f.stats.cache.depth_passes, 2) << "working set " << working_set << " MB, cache " << os.cache_mb;
    EXPECT_EQ(f.stats.cache.depth_pass, f.stats.cache.depth_passes - 1);
    EXPECT_LE(f.stats.cache.resident_mb, double(os.cache_mb));
    expect_same_image(f, ref.in_core);
    // Converged stays converged: the next frame casts the last pass again, to the same image.
    const Frame again = r.render(ref.scene(ref.cam), so);
    EXPECT_TRUE(r.converged());
    EXPECT_TRUE(again.image.rgba == f.image.rgba);
    // Another view ends the passes.
    EXPECT_EQ(r.render(ref.scene(opposite_view(d)), so).stats.cache.depth_passes, 0);
  }
}

std::vector<Case> cases(bool scalar) {
  std::vector<Case> v;
  for (const char* kind : {"neurites", "blobs", "organs", "sphere"})
    for (Mode m : {Mode::Dvr, Mode::DvrLit, Mode::DvrErt, Mode::DvrScalar, Mode::Mip, Mode::Iso, Mode::Labels})
      if ((m != Mode::Labels || generated_kind_has_labels(kind)) && (scalar || m != Mode::DvrScalar))
        v.push_back({kind, m});
  return v;
}

std::string case_name(const ::testing::TestParamInfo<Case>& i) { return i.param.kind + "_" + name(i.param.mode); }

INSTANTIATE_TEST_SUITE_P(BuiltInSets, OutOfCoreEqualsInCore, ::testing::ValuesIn(cases(true)), case_name);
// The passes carry the ray's state whichever loop composites (the scalar loop is covered above).
INSTANTIATE_TEST_SUITE_P(BuiltInSets, PinnedLevelInDepthPasses, ::testing::ValuesIn(cases(false)), case_name);

}  // namespace
}  // namespace sl
