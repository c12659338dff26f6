// The out-of-core caster's leaps (RayCaster::march_leaping, VirtualSampler::fine_cell): over the clear
// fine cells of resident bricks and of the resident ancestors that stand in for missing bricks, and
// over the stretches where nothing is resident and the one value served is clear. They change no
// frame: from the first frame (nothing resident) through fallbacks, evictions and pressure to
// convergence, the image and every count equal those of visiting every sample (RenderSettings::
// leaps off), frame by frame.
#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include <memory>
#include <string>

#include "cache/out_of_core/renderer.h"
#include "core/scene/generate.h"
#include "core/scene/labels.h"
#include "tests/test_util.h"

namespace sl {
namespace {

struct Data {
  std::shared_ptr<const Volume> volume, labels;
  std::uint32_t label_count = 0;
};

const Data& neurites() {
  static const Data d = [] {
    GeneratedVolume g = generate_volume("neurites", ivec3(72, 64, 56), 3);
    Data r;
    r.label_count = g.label_count;
    r.volume = std::make_shared<const Volume>(std::move(g.intensity));
    r.labels = std::make_shared<const Volume>(std::move(g.labels));
    return r;
  }();
  return d;
}

struct LeapRun {
  int frames = 0;
  int differing = 0;  // frames whose image or counts differ
  std::string first;  // what differed first
  double completeness_min = 1.0;
  std::uint64_t left_out = 0;
};

// Both renderers see the same frames: each waits for its loads between frames, and equal misses make
// equal requests.
LeapRun compare(const OutOfCoreSettings& os, const RenderSettings& s, const OutOfCoreScene& scene, PyramidKind pyramid,
            int frames) {
  const Data& d = neurites();
  auto source = std::make_shared<MemoryVolumeSource>(d.volume, d.labels, "neurites", pyramid);
  OutOfCoreRenderer leaping(source, os, s.block), visiting(source, os, s.block);
  RenderSettings off = s;
  off.leaps = false;
  LeapRun run;
  for (int i = 0; i < frames; ++i) {
    const Frame a = leaping.render(scene, s);
    const Frame b = visiting.render(scene, off);
    ++run.frames;
    run.completeness_min = std::min(run.completeness_min, a.stats.cache.completeness);
    run.left_out += a.stats.cache.samples_left_out;
    std::string why;
    if (test::max_abs_diff(a.image, b.image) != 0.0f) why = "image";
    if (a.stats.samples != b.stats.samples) why += " samples";
    if (a.stats.cache.samples_left_out != b.stats.cache.samples_left_out) why += " left-out";
    if (a.stats.cache.completeness != b.stats.cache.completeness) why += " completeness";
    if (a.stats.cache.lod_coarsened != b.stats.cache.lod_coarsened) why += " coarsened";
    if (a.stats.cache.misses != b.stats.cache.misses) why += " misses";
    if (!why.empty()) {
      if (run.differing++ == 0) run.first = "frame " + std::to_string(i + 1) + ":" + why;
    }
    if (leaping.converged() && visiting.converged()) break;
    leaping.wait_for_loads();
    visiting.wait_for_loads();
  }
  return run;
}

Camera close_camera(const vec3& extent, float zoom) {
  Camera c = default_camera(extent);
  c.eye = c.center + (c.eye - c.center) * zoom;
  return c;
}

TEST(OutOfCoreLeaps, EveryFrameEqualsVisitingEverySample) {
  const Data& d = neurites();
  const TransferFunction tf = default_transfer_function(0, 255);
  RenderSettings s;
  s.width = 64;
  s.height = 48;
  s.block = 8;
  OutOfCoreSettings os;
  os.brick = 16;
  os.cache_mb = 1;  // a fraction of the volume: fallbacks to ancestors, evictions and pressure
  const OutOfCoreScene scene{&tf, nullptr, close_camera(d.volume->desc().extent(), 0.5f)};
  const LeapRun run = compare(os, s, scene, PyramidKind::Max, 30);
  EXPECT_EQ(run.differing, 0) << run.first;
  EXPECT_LT(run.completeness_min, 1.0) << "the run must pass through incomplete frames";
  EXPECT_GT(run.left_out, 0u) << "the run must leap over clear cells";
}

RC_GTEST_PROP(OutOfCoreLeaps, NoFrameChangesForAnyWindowModeBrickOrLevel, ()) {
  const Data& d = neurites();
  const int lo = *rc::gen::inRange(0, 250);
  const int hi = *rc::gen::inRange(lo + 1, 256);
  const TransferFunction tf({TfPoint{float(lo), vec4(0.2f, 0.6f, 1.0f, 0.0f)},
                             TfPoint{float(hi), vec4(1.0f, 0.8f, 0.3f, *rc::gen::element(0.05f, 0.5f, 1.0f))}});
  const LabelSet enabled = parse_enable_spec("fraction:0.5:" + std::to_string(*rc::gen::inRange(1, 9)),
                                             d.label_count);
  RenderSettings s;
  s.width = 40;
  s.height = 32;
  s.block = 8;
  s.mode = *rc::gen::element(RenderMode::Dvr, RenderMode::Labels);
  s.ert = *rc::gen::arbitrary<bool>();
  OutOfCoreSettings os;
  os.brick = *rc::gen::element(8, 16);
  os.lod = *rc::gen::element(-1, -1, 0, 1);
  os.lod_bias = *rc::gen::element(0.5f, 1.0f, 2.0f);
  os.cache_mb = *rc::gen::element(1, 64);
  const bool label_mask = s.mode == RenderMode::Labels || *rc::gen::arbitrary<bool>();
  const float zoom = *rc::gen::element(1.0f, 0.6f, 0.3f);
  const OutOfCoreScene scene{&tf, label_mask ? &enabled : nullptr, close_camera(d.volume->desc().extent(), zoom)};
  const LeapRun run = compare(os, s, scene, *rc::gen::element(PyramidKind::Mean, PyramidKind::Max), 12);
  RC_ASSERT(run.differing == 0);
}

}  // namespace
}  // namespace sl
