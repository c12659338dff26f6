// Out of core under cache pressure (DESIGN.md "Virtual memory"): on a 256x192x128 u16 volume with u16
// labels (24 MiB together), caches below the view's working set must neither thrash nor stall; the
// automatic level of detail coarsens until the view fits and the frame is complete at its chosen
// levels; a pinned level reports the size it needs; a quarter-size cache whose view fits converges to
// the in-core image.
#include <gtest/gtest.h>

#include <algorithm>
#include <memory>

#include "cache/out_of_core/renderer.h"
#include "core/scene/generate.h"
#include "core/frame/in_core_renderer.h"

namespace sl {
namespace {

struct Data {
  std::shared_ptr<const Volume> volume, labels;
  std::uint32_t label_count = 0;
};

// The issue's volume: generated neurites, intensity widened to u16 (v * 257 spans the full range).
const Data& issue_volume() {
  static const Data d = [] {
    GeneratedVolume g = generate_volume("neurites", ivec3(256, 192, 128), 1);
    VolumeDesc desc = g.intensity.desc();
    desc.type = VoxelType::U16;
    Volume wide(desc);
    const std::uint8_t* src = g.intensity.as<std::uint8_t>();
    std::uint16_t* dst = wide.as<std::uint16_t>();
    for (std::uint64_t i = 0; i < desc.voxel_count(); ++i) dst[i] = std::uint16_t(src[i] * 257u);
    Data out;
    out.label_count = g.label_count;
    out.volume = std::make_shared<const Volume>(std::move(wide));
    out.labels = std::make_shared<const Volume>(std::move(g.labels));
    return out;
  }();
  return d;
}

struct ViewRun {
  std::vector<Frame> frames;
  bool converged = false;
};

// Renders up to `max_frames` frames of one view, letting the loader finish between frames (so a
// frame without loads while loads are pending is a stall, not a slow disk).
ViewRun run(OutOfCoreRenderer& r, const OutOfCoreScene& scene, const RenderSettings& s, int max_frames = 40) {
  ViewRun out;
  for (int i = 0; i < max_frames; ++i) {
    out.frames.push_back(r.render(scene, s));
    if (r.converged()) {
      out.converged = true;
      break;
    }
    r.wait_for_loads();
  }
  return out;
}

// Loads keep coming while any are pending: never two frames in a row with pending loads and none made.
void expect_progress(const ViewRun& run) {
  for (std::size_t i = 1; i < run.frames.size(); ++i) {
    const CacheStats& a = run.frames[i - 1].stats.cache;
    const CacheStats& b = run.frames[i].stats.cache;
    EXPECT_FALSE(a.pending > 0 && a.loads == 0 && b.pending > 0 && b.loads == 0) << "stall at frame " << b.frame;
  }
}

RenderSettings small_image() {
  RenderSettings s;
  s.width = 128;
  s.height = 96;
  return s;
}

OutOfCoreSettings cache(std::size_t mb, int lod, float lod_bias = 1.0f) {
  OutOfCoreSettings os;
  os.cache_mb = mb;
  os.lod = lod;
  os.lod_bias = lod_bias;
  return os;
}

std::shared_ptr<MemoryVolumeSource> source(const Data& d) {
  return std::make_shared<MemoryVolumeSource>(d.volume, d.labels, "issue14");
}

TEST(OutOfCorePressure, AutomaticLodCoarsensUntilTheViewFitsAndIsComplete) {
  const Data& d = issue_volume();
  const TransferFunction tf = default_transfer_function(0, 65535);
  const Camera cam = default_camera(d.volume->desc().extent());
  // Bias 0.5 at 128x96 asks for level 0 almost everywhere: about 100 bricks, the cache holds 53.
  OutOfCoreRenderer r(source(d), cache(8, -1, 0.5f), 16);
  const ViewRun out = run(r, OutOfCoreScene{&tf, nullptr, cam}, small_image());
  ASSERT_TRUE(out.converged) << "an 8 MB cache must converge with the automatic level of detail";
  expect_progress(out);
  const CacheStats& c = out.frames.back().stats.cache;
  EXPECT_EQ(c.completeness, 1.0) << "complete at the levels chosen for the samples";
  EXPECT_GT(c.lod_coarsened, 0.0) << "the view did not fit at its footprint's level";
  EXPECT_EQ(c.bricks_missing, 0u);
  EXPECT_GT(c.working_set_mb, c.cache_mb);
  EXPECT_EQ(c.working_set_level, 0);
  // Stable: more frames of the view neither load nor evict.
  for (int i = 0; i < 3; ++i) {
    const Frame f = r.render(OutOfCoreScene{&tf, nullptr, cam}, small_image());
    EXPECT_EQ(f.stats.cache.loads, 0u);
    EXPECT_EQ(f.stats.cache.evictions, 0u);
    EXPECT_TRUE(f.image.rgba == out.frames.back().image.rgba) << "the converged image changed";
  }
}

// A pinned level whose bricks do not fit settles short of complete, then goes on in depth passes
// (depth_passes.h) to the image a cache that holds the view renders, loading each brick a bounded
// number of times (a brick a pass boundary cuts is used by both passes).
TEST(OutOfCorePressure, PinnedLevelBelowTheWorkingSetNeverStallsOrThrashes) {
  const Data& d = issue_volume();
  const TransferFunction tf = default_transfer_function(0, 65535);
  const Camera cam = default_camera(d.volume->desc().extent());
  OutOfCoreRenderer whole(source(d), cache(64, 0), 16);
  const ViewRun all = run(whole, OutOfCoreScene{&tf, nullptr, cam}, small_image());
  ASSERT_TRUE(all.converged);
  const std::uint64_t view_bricks = all.frames.back().stats.cache.hits;
  for (const std::size_t mb : {std::size_t(16), std::size_t(24)}) {
    SCOPED_TRACE(std::to_string(mb) + " MB");
    OutOfCoreRenderer r(source(d), cache(mb, 0), 16);
    const ViewRun out = run(r, OutOfCoreScene{&tf, nullptr, cam}, small_image(), 400);
    ASSERT_TRUE(out.converged);
    expect_progress(out);
    std::uint64_t loads = 0;
    bool settled_short = false;
    for (const Frame& f : out.frames) {
      loads += f.stats.cache.loads;
      settled_short = settled_short || (f.stats.cache.depth_passes > 0 && f.stats.cache.depth_pass == 0);
    }
    EXPECT_TRUE(settled_short) << "the view does not fit: the passes start";
    EXPECT_LE(loads, 3 * view_bricks) << "no thrash: each of the view's " << view_bricks << " bricks loads a few times at most";
    const CacheStats& c = out.frames.back().stats.cache;
    EXPECT_GE(c.depth_passes, 2);
    EXPECT_EQ(c.pending, 0u);
    EXPECT_EQ(c.completeness, 1.0);
    EXPECT_EQ(c.lod_coarsened, 0.0) << "a pinned level is never coarsened";
    EXPECT_TRUE(out.frames.back().image.rgba == all.frames.back().image.rgba) << "the image of a cache that holds the view";
  }
}

TEST(OutOfCorePressure, PinnedLevelZeroWithEightMegabytesReportsTheSizeNeeded) {
  const Data& d = issue_volume();
  const TransferFunction tf = default_transfer_function(0, 65535);
  const Camera cam = default_camera(d.volume->desc().extent());
  OutOfCoreRenderer r(source(d), cache(8, 0), 16);
  // The frame that settles short of complete (and starts the depth passes) says what the view needs.
  CacheStats c;
  for (int i = 0; i < 40 && c.depth_passes == 0; ++i) {
    c = r.render(OutOfCoreScene{&tf, nullptr, cam}, small_image()).stats.cache;
    r.wait_for_loads();
  }
  ASSERT_GT(c.depth_passes, 0);
  EXPECT_LT(c.completeness, 1.0);
  EXPECT_EQ(c.working_set_level, 0);
  EXPECT_LE(c.cache_mb, 8.0);
  // Measured from the frame's requests: the resident bricks plus the known non-empty ones that did
  // not fit, i.e. more than the cache and at most the whole level 0 (24 MiB, 192 bricks).
  EXPECT_GT(c.working_set_mb, c.cache_mb + 1.0);
  EXPECT_LE(c.working_set_mb, 192.0 * double(34 * 34 * 34 * 4) / double(1 << 20));
}

TEST(OutOfCorePressure, QuarterCacheWithTenPercentOfLabelsConvergesToTheInCoreImage) {
  const Data& d = issue_volume();
  const TransferFunction tf = default_transfer_function(0, 65535);
  const LabelSet enabled = parse_enable_spec("fraction:0.1:1", d.label_count);
  const Camera cam = default_camera(d.volume->desc().extent());
  const RenderSettings s = small_image();
  const Frame in_core = InCoreRenderer().render(Scene{d.volume.get(), d.labels.get(), &tf, &enabled, cam}, s);
  OutOfCoreSettings os = cache(6, 0);  // a quarter of the 24 MiB
  os.brick = 16;
  OutOfCoreRenderer r(source(d), os, 16);
  const ViewRun out = run(r, OutOfCoreScene{&tf, &enabled, cam}, s);
  ASSERT_TRUE(out.converged);
  expect_progress(out);
  EXPECT_EQ(out.frames.back().stats.cache.completeness, 1.0);
  EXPECT_TRUE(out.frames.back().image.rgba == in_core.image.rgba) << "differs from the in-core image";
  float alpha = 0.0f;
  for (const vec4& c : in_core.image.rgba) alpha += c.w;
  EXPECT_GT(alpha, 1.0f) << "the comparison must not be of two empty images";
}

}  // namespace
}  // namespace sl
