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
  // The cache as a share of the volume's bytes in the cache (every brick with its apron, intensity
  // and labels): less than the volume, more than the view's working set (without culling, method
  // none, the rays need every brick they cross, empty or not).
  double share_sparseleap = 0.45, share_none = 0.7;
  TransferFunction tf = default_transfer_function(0, 255);
  std::string enable = "fraction:0.35:2";  // the labels masked in (dvr, mip, iso) or shown (labels mode)
};

const Data& data(const std::string& kind) {
  static std::vector<std::unique_ptr<Data>> all;
  for (const auto& d : all)
    if (d->kind == kind) return *d;
  auto d = std::make_unique<Data>();
  d->kind = kind;
  ivec3 dims(160, 144, 128);  // 2.8 MiB of u8 (+ 5.6 MiB of u16 labels)
  if (kind == "sphere") dims = ivec3(112, 96, 88);
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
    d->share_sparseleap = 0.7;  // 74 % of the voxels are not empty
  } else if (kind == "sphere") {
    // A shell of radius 18-26: the inside and the outside are culled.
    d->tf = TransferFunction({{16.0f, vec4(0.0f)},
                              {18.0f, {0.9f, 0.5f, 0.2f, 0.3f}},
                              {24.0f, {1.0f, 0.9f, 0.6f, 0.6f}},
                              {26.0f, vec4(0.0f)}});
    d->iso = 22;
    d->share_sparseleap = d->share_none = 0.85;  // mip culls nothing inside the shell
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

struct Case {
  std::string kind;
  Mode mode;
};

class OutOfCoreEqualsInCore : public ::testing::TestWithParam<Case> {};

TEST_P(OutOfCoreEqualsInCore, ConvergedFrameIsTheInCoreFrameForEveryMethod) {
  const Case& c = GetParam();
  const Data& d = data(c.kind);
  const TransferFunction& tf = d.tf;
  const LabelSet enabled = d.labels ? parse_enable_spec(d.enable, d.label_count) : LabelSet();
  const LabelSet* en = d.labels ? &enabled : nullptr;
  const RenderSettings s = settings(c.mode, d);
  const Camera cam = corner_view(d, vec3(0.32f, 0.36f, 0.4f), vec3(-0.55f, -0.7f, -0.45f));
  // Seen first, so that the test view's bricks replace the far corner's in the cache.
  const Camera other = corner_view(d, vec3(0.68f, 0.64f, 0.6f), vec3(0.6f, 0.65f, 0.5f));
  const Frame in_core = InCoreRenderer().render(Scene{d.volume.get(), d.labels.get(), &tf, en, cam}, s);
  float alpha = 0;
  for (const vec4& p : in_core.image.rgba) alpha += p.w;
  ASSERT_GT(alpha, 5.0f) << "the comparison must not be of two nearly empty images";

  OutOfCoreSettings os;
  os.brick = 16;
  const ivec3 bricks = (d.volume->desc().dims + os.brick - 1) / os.brick;
  const double voxel_bytes =
      double(voxel_size(d.volume->desc().type)) + (d.labels ? double(voxel_size(d.labels->desc().type)) : 0.0);
  const int stored = os.brick + 2 * kBrickApron;
  const double volume_mb = double(bricks.x) * bricks.y * bricks.z * stored * stored * stored * voxel_bytes / (1 << 20);
  os.lod = 0;
  auto source = std::make_shared<MemoryVolumeSource>(d.volume, d.labels, c.kind);
  for (SkipMethod method : {SkipMethod::SparseLeap, SkipMethod::None}) {
    SCOPED_TRACE(method == SkipMethod::None ? "out of core: none" : "out of core: sparseleap");
    RenderSettings so = s;
    so.method = method;
    // Less than the volume, more than one view's working set (without culling the rays need every
    // brick they cross, empty or not).
    os.cache_mb = std::size_t((method == SkipMethod::None ? d.share_none : d.share_sparseleap) * volume_mb);
    OutOfCoreRenderer r(source, os, s.block);
    Frame f;
    bool converged = false;
    std::uint64_t evictions = 0;
    for (const Camera& view : {other, cam}) {
      converged = false;
      evictions = 0;
      for (int i = 0; i < 80 && !converged; ++i) {
        f = r.render(OutOfCoreScene{&tf, en, view}, so);
        evictions += f.stats.cache.evictions;
        converged = r.converged();
        if (!converged) r.wait_for_loads();
      }
      ASSERT_TRUE(converged) << "did not converge in 80 frames";
    }
    EXPECT_GT(evictions, 0u) << "the cache must not hold both views' bricks";
    EXPECT_EQ(f.stats.cache.completeness, 1.0);
    EXPECT_LE(f.stats.cache.resident_mb, double(os.cache_mb));
    ASSERT_EQ(f.image.rgba.size(), in_core.image.rgba.size());
    std::size_t differing = 0, first = 0;
    float worst = 0;
    for (std::size_t i = 0; i < f.image.rgba.size(); ++i)
      if (f.image.rgba[i] != in_core.image.rgba[i]) {
        if (differing++ == 0) first = i;
        const vec4 e = glm::abs(f.image.rgba[i] - in_core.image.rgba[i]);
        worst = std::max(worst, std::max(std::max(e.x, e.y), std::max(e.z, e.w)));
      }
    EXPECT_EQ(differing, 0u) << "pixels differing from the in-core frame; the first at (" << first % s.width << ", "
                             << first / s.width << "), largest difference " << worst;
  }
}

std::vector<Case> cases() {
  std::vector<Case> v;
  for (const char* kind : {"neurites", "blobs", "organs", "sphere"})
    for (Mode m : {Mode::Dvr, Mode::DvrLit, Mode::DvrErt, Mode::DvrScalar, Mode::Mip, Mode::Iso, Mode::Labels})
      if (m != Mode::Labels || generated_kind_has_labels(kind)) v.push_back({kind, m});
  return v;
}

INSTANTIATE_TEST_SUITE_P(BuiltInSets, OutOfCoreEqualsInCore, ::testing::ValuesIn(cases()),
                         [](const ::testing::TestParamInfo<Case>& i) {
                           return i.param.kind + "_" + name(i.param.mode);
                         });

}  // namespace
}  // namespace sl
