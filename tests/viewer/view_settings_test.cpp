// Key bindings, the stats overlay's rows, and the render worker: the parts of the viewer's loop that
// need no window.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <chrono>
#include <memory>
#include <mutex>
#include <thread>

#include "apps/viewer/render_worker.h"
#include "apps/viewer/stats_rows.h"
#include "apps/viewer/view_settings.h"
#include "core/util/error.h"
#include "core/frame/in_core_renderer.h"
#include "core/scene/generate.h"

namespace sl::viewer {
namespace {

TEST(ViewKeys, DigitsSwitchTheMethod) {
  ViewSettings v;
  EXPECT_EQ(apply_key(v, '1'), KeyAction::Changed);
  EXPECT_EQ(v.render.method, SkipMethod::None);
  apply_key(v, '2');
  EXPECT_EQ(v.render.method, SkipMethod::BBox);
  apply_key(v, '3');
  EXPECT_EQ(v.render.method, SkipMethod::Octree);
  apply_key(v, '4');
  EXPECT_EQ(v.render.method, SkipMethod::SparseLeap);
}

TEST(ViewKeys, OutOfCoreIgnoresMethodsItCannotRender) {
  ViewSettings v;
  v.out_of_core = true;
  EXPECT_EQ(apply_key(v, '3'), KeyAction::None);
  EXPECT_EQ(apply_key(v, '2'), KeyAction::None);
  EXPECT_EQ(v.render.method, SkipMethod::SparseLeap);
  EXPECT_EQ(apply_key(v, '1'), KeyAction::Changed);
  EXPECT_EQ(v.render.method, SkipMethod::None);
  EXPECT_TRUE(method_available(v, SkipMethod::SparseLeap));
  EXPECT_FALSE(method_available(v, SkipMethod::Octree));
}

TEST(ViewKeys, MCyclesModesSkippingLabelsWithoutALabelVolume) {
  ViewSettings v;
  v.has_labels = false;
  std::vector<RenderMode> seen;
  for (int i = 0; i < 4; ++i) {
    apply_key(v, 'M');
    seen.push_back(v.render.mode);
  }
  EXPECT_EQ(seen, (std::vector<RenderMode>{RenderMode::Mip, RenderMode::Iso, RenderMode::Dvr, RenderMode::Mip}));
  v.has_labels = true;
  v.render.mode = RenderMode::Iso;
  apply_key(v, 'm');  // lower case too
  EXPECT_EQ(v.render.mode, RenderMode::Labels);
  apply_key(v, 'M');
  EXPECT_EQ(v.render.mode, RenderMode::Dvr);
}

TEST(ViewKeys, TogglesAndActions) {
  ViewSettings v;
  EXPECT_FALSE(v.render.boxes_overlay);
  apply_key(v, 'B');
  EXPECT_TRUE(v.render.boxes_overlay);
  apply_key(v, 'D');
  EXPECT_TRUE(v.render.depth_complexity_view);
  apply_key(v, 'd');
  EXPECT_FALSE(v.render.depth_complexity_view);
  EXPECT_EQ(apply_key(v, 'R'), KeyAction::ResetView);
  EXPECT_EQ(apply_key(v, 'S'), KeyAction::Screenshot);
  EXPECT_EQ(apply_key(v, 'K'), KeyAction::Keyframe);
  EXPECT_EQ(apply_key(v, 'Q'), KeyAction::None);
  EXPECT_EQ(apply_key(v, '5'), KeyAction::None);
}

TEST(ViewKeys, LightingIsoMethodAndFilterToggles) {
  ViewSettings v;
  EXPECT_EQ(apply_key(v, 'L'), KeyAction::Changed);
  EXPECT_TRUE(v.render.lighting.enabled);
  apply_key(v, 'l');
  EXPECT_FALSE(v.render.lighting.enabled);
  EXPECT_EQ(apply_key(v, 'E'), KeyAction::Changed);
  EXPECT_EQ(v.render.iso_method, IsoMethod::Sampled);
  apply_key(v, 'E');
  EXPECT_EQ(v.render.iso_method, IsoMethod::Exact);
  std::vector<Filter> seen;
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(apply_key(v, 'F'), KeyAction::Changed);
    seen.push_back(v.render.filter);
  }
  EXPECT_EQ(seen, (std::vector<Filter>{Filter::Quadratic, Filter::Cubic, Filter::Linear}));
  // Out of core the B-splines run with method none only: F is ignored under sparseleap, and with a
  // B-spline on, the digits keep to none.
  v.out_of_core = true;
  EXPECT_EQ(apply_key(v, 'F'), KeyAction::None);
  EXPECT_EQ(v.render.filter, Filter::Linear);
  apply_key(v, '1');
  EXPECT_EQ(apply_key(v, 'F'), KeyAction::Changed);
  EXPECT_EQ(v.render.filter, Filter::Quadratic);
  EXPECT_EQ(apply_key(v, '4'), KeyAction::None);
  EXPECT_EQ(v.render.method, SkipMethod::None);
}

TEST(ViewSettingsCompare, EveryFieldThatChangesTheImageCounts) {
  RenderSettings a, b;
  EXPECT_TRUE(same_settings(a, b));
  b.step = 0.25f;
  EXPECT_FALSE(same_settings(a, b));
  b = a;
  b.depth_complexity_view = true;
  EXPECT_FALSE(same_settings(a, b));
  b = a;
  b.width += 1;
  EXPECT_FALSE(same_settings(a, b));
  b = a;
  b.filter = Filter::Cubic;
  EXPECT_FALSE(same_settings(a, b));
  Camera c, d;
  EXPECT_TRUE(same_camera(c, d));
  d.eye.x += 1.0f;
  EXPECT_FALSE(same_camera(c, d));
}

TEST(StatsRows, ShowStageTimesWorkAndDepthComplexity) {
  Stats s;
  s.width = 320;
  s.height = 240;
  s.method = "sparseleap";
  s.mode = "dvr";
  s.time_ms.total = 12.5;
  s.time_ms.raycast = 10.25;
  s.samples = 12'345'678;
  s.boxes = 321;
  s.events = 4567;
  s.depth_complexity_min = 1;
  s.depth_complexity_avg = 2.5;
  s.depth_complexity_max = 9;
  const std::vector<StatRow> rows = stats_rows(s);
  auto value = [&](const std::string& label) {
    const auto it = std::find_if(rows.begin(), rows.end(), [&](const StatRow& r) { return r.label == label; });
    return it == rows.end() ? std::string("<missing>") : it->value;
  };
  EXPECT_EQ(value("frame ms"), "12.5");
  EXPECT_EQ(value("raycast"), "10.2");
  EXPECT_EQ(value("samples"), "12.35 M");
  EXPECT_EQ(value("boxes"), "321");
  EXPECT_EQ(value("events"), "4567");
  EXPECT_EQ(value("depth cx"), "1/2.50/9");
  for (const char* stage : {"metadata", "tree", "geometry", "order", "lists"}) EXPECT_NE(value(stage), "<missing>");
  EXPECT_EQ(pending_loads(s), 0u);
  EXPECT_FALSE(still_refining(s));
  EXPECT_EQ(value("resident MB"), "<missing>");  // in core: no cache rows
}

TEST(StatsRows, OutOfCoreFramesShowTheCacheAndRefineUntilNothingIsMissing) {
  Stats s;
  s.cache.present = true;
  s.cache.resident_mb = 37.25;
  s.cache.misses = 12;
  s.cache.pending = 3;
  s.cache.loads = 40;
  const std::vector<StatRow> rows = stats_rows(s);
  auto value = [&](const std::string& label) {
    const auto it = std::find_if(rows.begin(), rows.end(), [&](const StatRow& r) { return r.label == label; });
    return it == rows.end() ? std::string("<missing>") : it->value;
  };
  EXPECT_EQ(value("resident MB"), "37.2");
  EXPECT_EQ(value("misses"), "12");
  EXPECT_EQ(value("pending"), "3");
  EXPECT_EQ(value("loads"), "40");
  EXPECT_EQ(value("converged at"), "-");
  EXPECT_EQ(pending_loads(s), 3u);
  EXPECT_TRUE(still_refining(s));
  s.cache.pending = 0;
  EXPECT_TRUE(still_refining(s));  // not converged: misses are resolved by the next frame
  s.cache.misses = 0;
  s.cache.converged_at_frame = 7;
  EXPECT_FALSE(still_refining(s));
}

// A settled view under pressure keeps misses that no further frame resolves (bricks that do not fit at
// a pinned level): converged, incomplete, and not refining — the viewer must not repeat it forever.
TEST(StatsRows, ConvergedButIncompleteFramesStopRefining) {
  Stats s;
  s.cache.present = true;
  s.cache.misses = 64;
  s.cache.bricks_missing = 64;
  s.cache.completeness = 0.611;
  s.cache.converged_at_frame = 6;
  EXPECT_FALSE(still_refining(s));
  s.cache.converged_at_frame = -1;
  EXPECT_TRUE(still_refining(s));
}

TEST(StatsRows, HumanCounts) {
  EXPECT_EQ(human_count(17), "17");
  EXPECT_EQ(human_count(45'000), "45.0 k");
  EXPECT_EQ(human_count(2'500'000'000.0), "2.50 G");
}

TEST(DisplayImage, PremultipliedOverBlackSrgbEncodedOpaque) {
  Image img(2, 1);
  img.at(0, 0) = vec4(1.0f, 0.0f, 0.5f, 1.0f);
  img.at(1, 0) = vec4(0.0f, 2.0f, -1.0f, 0.0f);  // out of range: clamped
  const std::vector<std::uint8_t> px = to_display_rgba8(img);
  ASSERT_EQ(px.size(), 8u);
  EXPECT_EQ(px[0], 255);
  EXPECT_EQ(px[1], 0);
  EXPECT_EQ(px[2], std::lround(255.0f * linear_to_srgb(0.5f)));
  EXPECT_EQ(px[3], 255);
  EXPECT_EQ(px[5], 255);
  EXPECT_EQ(px[6], 0);
  EXPECT_EQ(px[7], 255);
}

// The display bytes are the PNG's (core/util/image.cpp write_png), so a full-resolution frame on screen is the
// image `render` writes: every 499th float in [0, 1] and the floats on either side of each code step.
TEST(DisplayImage, EncodesEveryValueAsThePngDoes) {
  std::vector<float> values;
  for (std::uint32_t bits = 0; bits <= std::bit_cast<std::uint32_t>(1.0f); bits += 499) {
    values.push_back(std::bit_cast<float>(bits));
  }
  for (int k = 0; k < 256; ++k) {
    // Where the code steps from k-1 to k, in the middle of the sRGB curve's inverse.
    const float v = (float(k) - 0.5f) / 255.0f;
    const float x = v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f);
    float y = x;
    for (int i = 0; i < 8; ++i) y = std::nextafter(y, 0.0f);
    for (int i = 0; i < 16; ++i, y = std::nextafter(y, 2.0f)) values.push_back(y);
  }
  values.push_back(1.0f);
  values.push_back(std::nextafter(1.0f, 0.0f));
  Image img(int(values.size()), 1);
  for (std::size_t i = 0; i < values.size(); ++i) img.rgba[i] = vec4(values[i], 0.0f, 0.0f, 1.0f);
  const std::vector<std::uint8_t> px = to_display_rgba8(img);
  std::size_t wrong = 0;
  for (std::size_t i = 0; i < values.size(); ++i) {
    const long png = std::lround(255.0f * linear_to_srgb(values[i]));
    if (px[i * 4] != png && ++wrong < 5) ADD_FAILURE() << values[i] << ": display " << int(px[i * 4]) << ", PNG " << png;
  }
  EXPECT_EQ(wrong, 0u) << "of " << values.size();
}

TEST(RenderWorker, RendersTheLatestJobAndReportsErrorsWithoutStopping) {
  const GeneratedVolume g = generate_volume("neurites", ivec3(24), 1);
  InCoreRenderer renderer;
  int calls = 0;
  RenderWorker w(&g.intensity, &g.labels, [&] {
    return RenderWorker::RenderFn([&](const Scene& s, const RenderSettings& r) {
      ++calls;
      return renderer.render(s, r);
    });
  });
  auto tf = std::make_shared<const TransferFunction>(default_transfer_function(0.0f, 255.0f));
  RenderJob job;
  job.id = 1;
  job.camera = default_camera(g.intensity.desc().extent());
  job.settings.width = 40;
  job.settings.height = 30;
  job.tf = tf;
  job.level = 2;  // the viewer's progressive level travels with the frame
  w.submit(job);
  w.wait_idle();
  std::optional<RenderResult> r = w.take();
  ASSERT_TRUE(r.has_value());
  EXPECT_TRUE(r->error.empty()) << r->error;
  EXPECT_EQ(r->id, 1u);
  EXPECT_EQ(r->width, 40);
  EXPECT_EQ(r->rgba8.size(), 40u * 30u * 4u);
  EXPECT_GT(r->stats.samples, 0u);
  EXPECT_EQ(r->level, 2);
  EXPECT_GT(r->worker_ms, 0.0);
  EXPECT_FALSE(w.take().has_value());  // taken once

  job.id = 2;
  job.camera.center = job.camera.eye;  // degenerate view: the renderer throws
  w.submit(job);
  w.wait_idle();
  r = w.take();
  ASSERT_TRUE(r.has_value());
  EXPECT_FALSE(r->error.empty());

  job.id = 3;
  job.camera = default_camera(g.intensity.desc().extent());
  w.submit(job);
  w.wait_idle();
  r = w.take();
  ASSERT_TRUE(r.has_value());
  EXPECT_TRUE(r->error.empty());
  EXPECT_EQ(calls, 3);
}

TEST(RenderWorker, ANewerJobReplacesOneNotYetStarted) {
  const GeneratedVolume g = generate_volume("neurites", ivec3(16), 1);
  InCoreRenderer renderer;
  std::vector<std::uint64_t> rendered;
  auto tf = std::make_shared<const TransferFunction>(default_transfer_function(0.0f, 255.0f));
  std::mutex gate;
  gate.lock();  // holds the first frame until three more jobs are queued
  std::atomic<bool> started{false};
  RenderWorker w(&g.intensity, nullptr, [&] {
    return RenderWorker::RenderFn([&](const Scene& s, const RenderSettings& r) {
      started = true;
      std::lock_guard hold(gate);
      rendered.push_back(std::uint64_t(r.width));
      return renderer.render(s, r);
    });
  });
  RenderJob job;
  job.camera = default_camera(g.intensity.desc().extent());
  job.tf = tf;
  job.settings.height = 8;
  for (int width : {8, 9, 10, 11}) {
    job.settings.width = width;
    w.submit(job);
    while (!started) std::this_thread::sleep_for(std::chrono::milliseconds(1));  // the first one is running
  }
  gate.unlock();
  w.wait_idle();
  EXPECT_EQ(rendered, (std::vector<std::uint64_t>{8, 11}));
  const std::optional<RenderResult> r = w.take();
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->width, 11);  // the newest frame; the older finished one was dropped
}

TEST(RenderWorker, MakesUsesAndDestroysTheRendererOnItsOwnThread) {
  const GeneratedVolume g = generate_volume("neurites", ivec3(16), 1);
  struct Owner {
    std::thread::id* destroyed_on;
    ~Owner() { *destroyed_on = std::this_thread::get_id(); }
  };
  std::thread::id made_on, rendered_on, destroyed_on;
  {
    RenderWorker w(&g.intensity, nullptr, [&] {
      made_on = std::this_thread::get_id();
      auto owner = std::make_shared<Owner>(Owner{&destroyed_on});
      auto renderer = std::make_shared<InCoreRenderer>();
      return RenderWorker::RenderFn([&, owner, renderer](const Scene& s, const RenderSettings& r) {
        rendered_on = std::this_thread::get_id();
        return renderer->render(s, r);
      });
    });
    EXPECT_NE(made_on, std::this_thread::get_id());  // made before the constructor returned
    RenderJob job;
    job.camera = default_camera(g.intensity.desc().extent());
    job.tf = std::make_shared<const TransferFunction>(default_transfer_function(0.0f, 255.0f));
    job.settings.width = job.settings.height = 8;
    w.submit(job);
    w.wait_idle();
    ASSERT_TRUE(w.take().has_value());
  }
  EXPECT_EQ(rendered_on, made_on);
  EXPECT_EQ(destroyed_on, made_on);
}

TEST(RenderWorker, ARendererThatCannotBeMadeFailsTheConstructor) {
  const GeneratedVolume g = generate_volume("neurites", ivec3(8), 1);
  EXPECT_THROW(RenderWorker(&g.intensity, nullptr,
                            []() -> RenderWorker::RenderFn { throw InputError("--cache-mb", "too small"); }),
               InputError);
}

}  // namespace
}  // namespace sl::viewer
