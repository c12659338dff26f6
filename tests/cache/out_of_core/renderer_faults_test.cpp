// The out-of-core renderer under injected I/O faults: it renders every frame, reports each
// failed brick once, retries transient faults, converges, and equals the in-core image wherever no
// ray touches a brick that failed for good.
#include <gtest/gtest.h>

#include <memory>
#include <regex>
#include <set>

#include "cache/testing/fault_injection.h"
#include "cache/out_of_core/renderer.h"
#include "core/scene/generate.h"
#include "core/frame/in_core_renderer.h"

namespace sl {
namespace {

struct FaultRun {
  Frame frame;
  std::size_t frames = 0;
  bool converged = false;
  std::string err;                          // the renderer's warnings
  std::vector<BrickId> failed;              // bricks the loader failed for good
  std::vector<BrickId> expected_failures;   // bricks read whose spec fault is permanent
  BrickLayout layout;
};

// Renders until converged (the loader settles between frames, so the frame count does not depend
// on timing), checking that every frame renders.
FaultRun render_with_faults(const GeneratedVolume& g, const FaultSpec& spec, const Camera& cam, const RenderSettings& s,
                       const TransferFunction& tf) {
  auto inner = std::make_shared<MemoryVolumeSource>(std::make_shared<const Volume>(g.intensity),
                                                    std::make_shared<const Volume>(g.labels), "neurites");
  auto src = std::make_shared<FaultInjectingSource>(inner, spec);
  OutOfCoreSettings os;
  os.brick = 16;
  os.lod = 0;
  os.cache_mb = 64;  // everything fits: only faults keep bricks out
  os.retry.first_backoff = std::chrono::milliseconds(1);
  os.retry.max_backoff = std::chrono::milliseconds(8);
  OutOfCoreRenderer r(src, os, 16);
  FaultRun run;
  run.layout = r.layout();
  testing::internal::CaptureStderr();
  for (; run.frames < 80 && !run.converged; ++run.frames) {
    run.frame = r.render(OutOfCoreScene{&tf, nullptr, cam}, s);
    EXPECT_EQ(run.frame.image.rgba.size(), std::size_t(s.width) * std::size_t(s.height));
    // The loader's threads may fail a brick after the frame took its counts: never fewer than counted.
    EXPECT_LE(run.frame.stats.cache.failed, r.failed_bricks());
    run.converged = r.converged();
    r.wait_for_loads();
  }
  // A converged frame waited for nothing, so nothing failed after it.
  if (run.converged) {
    EXPECT_EQ(run.frame.stats.cache.failed, r.failed_bricks());
  }
  run.err = testing::internal::GetCapturedStderr();
  for (int level = 0; level < run.layout.levels; ++level) {
    const ivec3 n = run.layout.bricks(level);
    for (int z = 0; z < n.z; ++z)
      for (int y = 0; y < n.y; ++y)
        for (int x = 0; x < n.x; ++x) {
          const BrickId id = BrickId::pack(level, {x, y, z});
          if (r.page_entry(id).is_resident()) {
            EXPECT_NE(spec.fault(id).kind, FaultKind::Permanent);
          }
          if (src->attempts(id) > 0 && spec.fault(id).kind == FaultKind::Permanent) run.expected_failures.push_back(id);
        }
  }
  // The loader's verdicts, from the warnings' brick ids (checked against failed_bricks() below).
  static const std::regex re("rendered as missing: neurites: level ([0-9]+) brick \\(([0-9]+), ([0-9]+), ([0-9]+)\\): ");
  for (auto it = std::sregex_iterator(run.err.begin(), run.err.end(), re); it != std::sregex_iterator(); ++it) {
    const std::smatch& m = *it;
    run.failed.push_back(BrickId::pack(std::stoi(m[1]), {std::stoi(m[2]), std::stoi(m[3]), std::stoi(m[4])}));
  }
  EXPECT_EQ(run.failed.size(), r.failed_bricks()) << run.err;
  return run;
}

// Pixels whose ray passes within reach of a failed brick: its payload box grown by two voxels (the
// trilinear footprint and the gradient's central differences read one voxel beyond a sample).
std::vector<bool> touched_pixels(const FaultRun& run, const Camera& cam, const RenderSettings& s) {
  const RayGenerator gen = make_ray_generator(cam, s.width, s.height);
  std::vector<bool> touched(std::size_t(s.width) * std::size_t(s.height), false);
  for (const BrickId id : run.failed) {
    const vec3 sp = run.layout.level_spacing(id.level());
    const vec3 lo = vec3(run.layout.brick_origin(id)) * sp - 2.0f * sp;
    const vec3 hi = vec3(run.layout.brick_origin(id) + run.layout.brick_size) * sp + 2.0f * sp;
    for (int y = 0; y < s.height; ++y)
      for (int x = 0; x < s.width; ++x) {
        if (!intersect(gen.ray(x, y), Box3{lo, hi}).empty()) touched[std::size_t(y) * s.width + x] = true;
      }
  }
  return touched;
}

struct Scenario {
  GeneratedVolume g = generate_volume("neurites", ivec3(64, 64, 64), 4);
  TransferFunction tf = default_transfer_function(0, 255);
  Camera cam = default_camera(vec3(64.0f));
  RenderSettings s;
  Frame in_core;
  Scenario() {
    s.width = 48;
    s.height = 40;
    in_core = InCoreRenderer().render(Scene{&g.intensity, &g.labels, &tf, nullptr, cam}, s);
  }
};

TEST(OutOfCoreFaults, TenPercentMixedFaultsRenderConvergeAndMatchInCoreAwayFromLostBricks) {
  const Scenario sc;
  std::size_t with_failures = 0;
  for (std::uint64_t seed = 1; seed <= 4; ++seed) {
    FaultSpec spec;
    spec.permanent = 0.03;
    spec.transient = 0.05;
    spec.short_read = 0.02;
    spec.delay = 0.1;
    spec.delay_ms = 1;
    spec.seed = seed;
    const FaultRun run = render_with_faults(sc.g, spec, sc.cam, sc.s, sc.tf);
    SCOPED_TRACE("seed " + std::to_string(seed));
    ASSERT_TRUE(run.converged) << run.frames << " frames";
    const CacheStats& c = run.frame.stats.cache;
    // Each failed brick reported exactly once, and exactly the permanent ones among those read
    // (recover = 2 < 5 attempts: every transient fault recovers).
    std::set<BrickId> failed(run.failed.begin(), run.failed.end());
    EXPECT_EQ(failed.size(), run.failed.size()) << run.err;
    EXPECT_EQ(failed, std::set<BrickId>(run.expected_failures.begin(), run.expected_failures.end())) << run.err;
    EXPECT_EQ(c.failed, failed.size());
    EXPECT_GT(c.bricks_retried, 0u);
    EXPECT_EQ(c.recovered, c.bricks_retried);
    EXPECT_GE(c.retries, c.bricks_retried);
    EXPECT_EQ(c.bricks_missing, 0u);
    EXPECT_EQ(c.pending, 0u);
    // Short of complete exactly when data were lost.
    if (failed.empty()) {
      EXPECT_EQ(c.completeness, 1.0);
    } else {
      ++with_failures;
      EXPECT_LT(c.completeness, 1.0);
    }
    const std::vector<bool> touched = touched_pixels(run, sc.cam, sc.s);
    std::size_t compared = 0;
    for (std::size_t i = 0; i < touched.size(); ++i) {
      if (touched[i]) continue;
      ++compared;
      const vec4 d = glm::abs(run.frame.image.rgba[i] - sc.in_core.image.rgba[i]);
      ASSERT_LE(std::max({d.x, d.y, d.z, d.w}), 1e-5f) << "pixel " << i % sc.s.width << ", " << i / sc.s.width;
    }
    EXPECT_GT(compared, touched.size() / 4);
  }
  EXPECT_GT(with_failures, 0u) << "some seed must lose bricks";
}

TEST(OutOfCoreFaults, OnlyTransientFaultsConvergeToTheInCoreImageCompletely) {
  const Scenario sc;
  FaultSpec spec;
  spec.transient = 0.08;
  spec.short_read = 0.02;
  spec.recover = 3;
  spec.seed = 9;
  const FaultRun run = render_with_faults(sc.g, spec, sc.cam, sc.s, sc.tf);
  ASSERT_TRUE(run.converged);
  const CacheStats& c = run.frame.stats.cache;
  EXPECT_TRUE(run.failed.empty()) << run.err;
  EXPECT_TRUE(run.err.empty()) << run.err;
  EXPECT_EQ(c.failed, 0u);
  EXPECT_GT(c.bricks_retried, 0u);
  EXPECT_EQ(c.recovered, c.bricks_retried);
  EXPECT_EQ(c.completeness, 1.0);
  float diff = 0.0f, alpha = 0.0f;
  for (std::size_t i = 0; i < run.frame.image.rgba.size(); ++i) {
    const vec4 d = glm::abs(run.frame.image.rgba[i] - sc.in_core.image.rgba[i]);
    diff = std::max({diff, d.x, d.y, d.z, d.w});
    alpha += sc.in_core.image.rgba[i].w;
  }
  EXPECT_LE(diff, 1e-5f);
  EXPECT_GT(alpha, 1.0f) << "the comparison must not be of two empty images";
}

TEST(OutOfCoreFaults, TransientFaultsOutlastingTheAttemptsFailLikePermanentOnes) {
  const Scenario sc;
  FaultSpec spec;
  spec.transient = 0.1;
  spec.recover = 1000;  // k uniform in [1, 1000]: nearly all outlast 5 attempts
  spec.seed = 3;
  const FaultRun run = render_with_faults(sc.g, spec, sc.cam, sc.s, sc.tf);
  ASSERT_TRUE(run.converged);
  const CacheStats& c = run.frame.stats.cache;
  EXPECT_GT(c.failed, 0u);
  EXPECT_LT(c.completeness, 1.0);
  EXPECT_EQ(c.bricks_retried, c.failed + c.recovered);
  EXPECT_NE(run.err.find("(still failing after 5 attempts)"), std::string::npos) << run.err;
}

}  // namespace
}  // namespace sl
