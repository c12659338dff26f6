// Helpers of the GL suites: one headless context per process (skipping with the reason when none
// can be made, failing under CI), random occupancy fixtures on odd grids, cameras, and list comparison.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <memory>
#include <string>

#include "core/scene/camera.h"
#include "core/occupancy/occupancy_geometry.h"
#include "core/occupancy/occupancy_tree.h"
#include "core/lists/segment_list.h"
#include "core/lists/visibility_order.h"
#include "gl/gl_context.h"
#include "tests/test_util.h"

namespace sl::test {

// The process's headless context, made on first use; null (with the reason) when none can be made.
// It is never destroyed: destroying the last context terminates the EGL display, which unloads Mesa's
// driver before LeakSanitizer reports, and the driver's own process-lifetime allocations then show
// up under no module name, beyond the reach of the suppressions in gl_context_test.cpp.
inline GlContext* shared_gl_context(std::string* reason = nullptr) {
  static GlContext* context = nullptr;
  static std::string error;
  static bool tried = false;
  if (!tried) {
    tried = true;
    try {
      context = GlContext::create_headless().release();
      std::printf("[ GL       ] %s\n", context->info().summary().c_str());
    } catch (const GlError& e) {
      error = e.what();
    }
  }
  if (reason) *reason = error;
  return context;
}

// Skips the calling test (fails it under CI), saying why, when there is no GL context; otherwise binds
// `ctx` to it.
#define SL_REQUIRE_GL(ctx)                                                          \
  std::string sl_gl_reason_;                                                        \
  ::sl::GlContext* ctx = ::sl::test::shared_gl_context(&sl_gl_reason_);             \
  if (!ctx) SL_SKIP_OR_FAIL("no OpenGL context: " + sl_gl_reason_);                 \
  ctx->make_current()

struct GlFixture {
  OccupancyTree tree;
  OccupancyGeometry geometry;
};

// A random tree (make_random_occupancy_tree) over an odd grid with at least `min_boxes` boxes.
inline GlFixture random_gl_fixture(std::uint64_t seed, ivec3 dims, vec3 spacing, int depth, std::size_t min_boxes,
                                   int block = 4) {
  const BlockGrid grid = make_block_grid(dims, spacing, block);
  for (;; ++seed) {
    GlFixture f{make_random_occupancy_tree(grid, seed, RandomTreeParams{depth, 0.75, 0.5}), {}};
    f.geometry = build_occupancy_geometry(f.tree);
    if (f.geometry.boxes.size() >= min_boxes) return f;
  }
}

inline Camera gl_perspective(vec3 eye, vec3 center, float fov = 40.0f) {
  Camera c;
  c.eye = eye;
  c.center = center;
  c.up = vec3(0.0f, 1.0f, 0.0f);
  c.fov_deg = fov;
  return c;
}

inline Camera gl_orthographic(vec3 eye, vec3 center, float height) {
  Camera c = gl_perspective(eye, center);
  c.projection = Projection::Orthographic;
  c.height = height;
  return c;
}

struct ListDiff {
  std::size_t count_mismatches = 0;  // count words differ (events or overflow flag)
  std::size_t class_mismatches = 0;  // same count, some event's class or type differs
  std::size_t t_out_of_tolerance = 0;
  std::size_t t_not_bitwise = 0;     // within tolerance but not the same float
  std::size_t first_bad_pixel = std::size_t(-1);
  bool same() const { return count_mismatches + class_mismatches + t_out_of_tolerance == 0; }
};

// The criterion: same counts, classes and types exact, t within `rel` relative.
inline ListDiff compare_lists(const SegmentListBuffer& gl, const SegmentListBuffer& cpu, float rel = 1e-4f) {
  ListDiff d;
  EXPECT_EQ(gl.width, cpu.width);
  EXPECT_EQ(gl.height, cpu.height);
  if (gl.counts.size() != cpu.counts.size()) {
    d.count_mismatches = 1;
    return d;
  }
  for (std::size_t i = 0; i < cpu.counts.size(); ++i) {
    bool bad = false;
    if (gl.counts[i] != cpu.counts[i]) {
      ++d.count_mismatches;
      bad = true;
    } else {
      for (std::uint32_t k = 0; k < cpu.count(i); ++k) {
        const RayEvent& a = gl.list(i)[k];
        const RayEvent& b = cpu.list(i)[k];
        if (a.cls != b.cls || a.type != b.type || a.pad != b.pad) {
          ++d.class_mismatches;
          bad = true;
          break;
        }
        if (std::fabs(a.t - b.t) > rel * std::fmax(std::fabs(a.t), std::fabs(b.t))) {
          ++d.t_out_of_tolerance;
          bad = true;
          break;
        }
        if (std::memcmp(&a.t, &b.t, sizeof(float)) != 0) ++d.t_not_bitwise;
      }
    }
    if (bad && d.first_bad_pixel == std::size_t(-1)) d.first_bad_pixel = i;
  }
  return d;
}

inline std::string describe_pixel(const SegmentListBuffer& b, std::size_t i) {
  if (i >= b.counts.size()) return "none";
  std::string s = "pixel (" + std::to_string(i % std::size_t(b.width)) + ", " +
                  std::to_string(i / std::size_t(b.width)) + ") count " + std::to_string(b.count(i)) +
                  (b.overflowed(i) ? " overflow" : "") + ":";
  for (std::uint32_t k = 0; k < b.count(i); ++k) {
    char buf[64];
    std::snprintf(buf, sizeof buf, " [%.9g %s %s]", double(b.list(i)[k].t), b.list(i)[k].type == 0 ? "in" : "out",
                  to_string(OccupancyClass(b.list(i)[k].cls)));
    s += buf;
  }
  return s;
}

// Lists equal in the sense; on llvmpipe (IEEE float ops, no contraction under `precise`)
// the t values are also required to be the very same floats.
inline void expect_same_lists(const GlContext& ctx, const SegmentListBuffer& gl, const SegmentListBuffer& cpu) {
  const ListDiff d = compare_lists(gl, cpu);
  EXPECT_TRUE(d.same()) << d.count_mismatches << " count, " << d.class_mismatches << " class, "
                        << d.t_out_of_tolerance << " t mismatches; first: GL "
                        << describe_pixel(gl, d.first_bad_pixel) << " vs CPU "
                        << describe_pixel(cpu, d.first_bad_pixel);
  if (ctx.info().renderer.find("llvmpipe") != std::string::npos) {
    EXPECT_EQ(d.t_not_bitwise, 0u) << "t within tolerance but not bitwise equal on llvmpipe";
  }
}

}  // namespace sl::test
