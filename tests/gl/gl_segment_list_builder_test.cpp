// The GL segment-list builder (paper §7, §9; Alg. 4-5) equals the CPU tile builder for random trees
// on odd grids, cameras outside, inside and orthographic, grazing rays, the short-gap rule, small
// capacities, scrambled fragment order, bands, and conservative record overflow. Headless on
// llvmpipe (the fallback path); skipped, saying why, where no GL context can be made.
#include "gl/gl_segment_list_builder.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>
#include <random>

#include "core/lists/segment_list_builder.h"
#include "tests/gl/gl_test_util.h"

namespace sl {
namespace {

using test::GlFixture;
using test::gl_orthographic;
using test::gl_perspective;
using test::random_gl_fixture;

struct Built {
  RayGenerator gen;
  std::vector<VisibilityEntry> order;
  SegmentListBuffer cpu, gl;
  GlBuildStats stats;
};

// GL lists of `capacity` events per pixel against the CPU's: the tile builder's (no capacity) at
// kMaxEvents, where these fixtures' lists fit; below it the reference bounded to the same capacity.
Built build_both(GlSegmentListBuilder& b, const GlFixture& f, const Camera& cam, int w, int h, float eps = 0.0f,
                 std::uint32_t capacity = kMaxEvents) {
  Built r;
  r.gen = make_ray_generator(cam, w, h);
  r.order = build_visibility_order(f.tree, f.geometry, view_point(r.gen));
  if (capacity < kMaxEvents) {
    build_segment_lists_reference(f.geometry, r.order, r.gen, r.cpu, eps, capacity);
  } else {
    build_segment_lists(f.geometry, r.order, r.gen, r.cpu, eps);
  }
  r.stats = b.build(f.geometry, r.order, r.gen, capacity, eps);
  b.read_back(r.gl, &r.stats);
  return r;
}

void check_equal(GlContext& ctx, GlSegmentListBuilder& b, const GlFixture& f, const Camera& cam, int w, int h,
                 float eps = 0.0f, std::uint32_t capacity = kMaxEvents) {
  const Built r = build_both(b, f, cam, w, h, eps, capacity);
  test::expect_same_lists(ctx, r.gl, r.cpu);
  EXPECT_EQ(r.stats.dropped_pixels, 0u);
  EXPECT_GT(r.stats.lists.lists, 0u);
  EXPECT_EQ(r.stats.lists.events, segment_list_stats(r.cpu).events);
  EXPECT_EQ(r.gl.event_count, r.stats.lists.events);  // read back compactly
}

// Hit entries per pixel, brute force: the records the fallback appends (Alg. 4's hit rule).
std::vector<std::uint32_t> hits_per_pixel(const GlFixture& f, const Built& r) {
  std::vector<std::uint32_t> n(std::size_t(r.gen.width) * r.gen.height, 0u);
  for (int y = 0; y < r.gen.height; ++y) {
    for (int x = 0; x < r.gen.width; ++x) {
      const Ray ray = r.gen.ray(x, y);
      for (const VisibilityEntry& e : r.order) {
        const Interval iv = intersect(ray, f.geometry.boxes[e.box].box);
        if (!iv.empty() && iv.t1 > 0.0f) ++n[std::size_t(y) * r.gen.width + x];
      }
    }
  }
  return n;
}

// Pixels made conservative: an open list (overflow flag) with one NON_EMPTY entry no later than the
// CPU list's first event, so the caster samples everything the exact list would.
void expect_conservative(const Built& r, std::size_t i) {
  ASSERT_TRUE(r.gl.overflowed(i));
  ASSERT_EQ(r.gl.count(i), 1u);
  EXPECT_EQ(OccupancyClass(r.gl.list(i)[0].cls), OccupancyClass::NonEmpty);
  ASSERT_GT(r.cpu.count(i), 0u);
  EXPECT_LE(r.gl.list(i)[0].t, r.cpu.list(i)[0].t * (1.0f + 1e-6f) + 1e-6f);
}

const GlFixture& odd_fixture() {  // 61 x 64 x 45 voxels, anisotropic spacing, 16 x 16 x 12 blocks
  static const GlFixture f = random_gl_fixture(11, ivec3(61, 64, 45), vec3(1.0f, 0.5f, 2.0f), 4, 300);
  return f;
}

const GlFixture& large_fixture() {  // thousands of boxes: 125 x 97 x 83 voxels, 32 x 25 x 21 blocks
  static const GlFixture f = random_gl_fixture(5, ivec3(125, 97, 83), vec3(1.0f), 5, 2000);
  return f;
}

TEST(GlSegmentListBuilder, ReportsItsPath) {
  SL_REQUIRE_GL(ctx);
  GlSegmentListBuilder b(*ctx);
  std::printf("[ GL       ] renderer '%s', segment-list path: %s\n", ctx->info().renderer.c_str(), to_string(b.path()));
  EXPECT_EQ(b.path(), ctx->info().interlock() ? GlListPath::Interlock : GlListPath::Fallback);
  GlBuilderOptions o;
  o.path = GlBuilderOptions::Path::Fallback;
  EXPECT_EQ(GlSegmentListBuilder(*ctx, o).path(), GlListPath::Fallback);
  if (!ctx->info().interlock()) {
    o.path = GlBuilderOptions::Path::Interlock;
    try {
      GlSegmentListBuilder forced(*ctx, o);
      ADD_FAILURE() << "interlock forced without the extension must throw";
    } catch (const GlError& e) {
      EXPECT_NE(std::string(e.what()).find("GL_ARB_fragment_shader_interlock"), std::string::npos) << e.what();
    }
  }
}

TEST(GlSegmentListBuilder, EqualsCpuBuilderPerspectiveOutside) {
  SL_REQUIRE_GL(ctx);
  GlSegmentListBuilder b(*ctx);
  const GlFixture& f = odd_fixture();
  std::printf("[ GL       ] %zu boxes\n", f.geometry.boxes.size());
  check_equal(*ctx, b, f, gl_perspective(vec3(100.0f, 70.0f, 150.0f), vec3(30.0f, 16.0f, 45.0f)), 61, 47);
  check_equal(*ctx, b, f, gl_perspective(vec3(-40.0f, 20.0f, -30.0f), vec3(30.0f, 17.0f, 40.0f), 70.0f), 128, 96);
  check_equal(*ctx, b, f, gl_perspective(vec3(30.0f, 120.0f, 45.0f), vec3(30.0f, 16.0f, 45.5f), 50.0f), 61, 47);
}

TEST(GlSegmentListBuilder, EqualsCpuBuilderOrthographic) {
  SL_REQUIRE_GL(ctx);
  GlSegmentListBuilder b(*ctx);
  const GlFixture& f = odd_fixture();
  check_equal(*ctx, b, f, gl_orthographic(vec3(100.0f, -50.0f, 80.0f), vec3(30.0f, 16.0f, 45.0f), 110.0f), 61, 47);
  check_equal(*ctx, b, f, gl_orthographic(vec3(-60.0f, 40.0f, 200.0f), vec3(30.0f, 16.0f, 45.0f), 95.0f), 128, 96);
}

TEST(GlSegmentListBuilder, EqualsCpuBuilderCameraInside) {
  SL_REQUIRE_GL(ctx);
  GlSegmentListBuilder b(*ctx);
  const GlFixture& f = odd_fixture();
  check_equal(*ctx, b, f, gl_perspective(vec3(20.0f, 15.0f, 40.0f), vec3(50.0f, 16.0f, 10.0f), 90.0f), 61, 47);
  check_equal(*ctx, b, f, gl_perspective(vec3(31.0f, 9.0f, 60.0f), vec3(31.0f, 30.0f, 61.0f), 120.0f), 128, 96);
  check_equal(*ctx, b, f, gl_orthographic(vec3(20.0f, 15.0f, 40.0f), vec3(50.0f, 16.0f, 10.0f), 60.0f), 61, 47);
}

TEST(GlSegmentListBuilder, EqualsCpuBuilderThousandsOfBoxes) {
  SL_REQUIRE_GL(ctx);
  GlSegmentListBuilder b(*ctx);
  const GlFixture& f = large_fixture();
  std::printf("[ GL       ] %zu boxes\n", f.geometry.boxes.size());
  check_equal(*ctx, b, f, gl_perspective(vec3(190.0f, 140.0f, 230.0f), vec3(62.0f, 48.0f, 41.0f), 35.0f), 128, 96);
  check_equal(*ctx, b, f, gl_perspective(vec3(60.0f, 50.0f, 40.0f), vec3(0.0f, 45.0f, 80.0f), 100.0f), 61, 47);
}

TEST(GlSegmentListBuilder, EqualsCpuBuilderGrazingFacesAndEdges) {
  SL_REQUIRE_GL(ctx);
  GlSegmentListBuilder b(*ctx);
  // Volume [0,1]^3 of 16 blocks per axis. Orthographic and axis-aligned with 1/16 pixels: ray origins
  // lie on block planes, so rays run along faces and edges (dir == 0 axes, t0 == t1 grazing).
  const GlFixture f = random_gl_fixture(3, ivec3(64), vec3(1.0f / 64.0f), 4, 40);
  check_equal(*ctx, b, f, gl_orthographic(vec3(0.5f, 0.5f, 3.0f), vec3(0.5f, 0.5f, 0.0f), 17.0f / 16.0f), 17, 17);
  check_equal(*ctx, b, f, gl_perspective(vec3(0.5f, 0.5f, 2.5f), vec3(0.5f, 0.5f, 0.0f), 35.0f), 33, 33);
  check_equal(*ctx, b, f, gl_perspective(vec3(0.25f, 0.5f, 0.5f), vec3(0.25f, 0.5f, -1.0f), 100.0f), 31, 31);
}

TEST(GlSegmentListBuilder, ShortGapRuleAndSmallCapacityMatch) {
  SL_REQUIRE_GL(ctx);
  GlSegmentListBuilder b(*ctx);
  const GlFixture& f = odd_fixture();
  const Camera cam = gl_perspective(vec3(100.0f, 70.0f, 150.0f), vec3(30.0f, 16.0f, 45.0f));
  check_equal(*ctx, b, f, cam, 61, 47, 0.5f);
  check_equal(*ctx, b, f, cam, 61, 47, 3.0f);
  const Built r = build_both(b, f, cam, 61, 47, 0.0f, 3u);  // Alg. 5 overflow: open, conservative tails
  test::expect_same_lists(*ctx, r.gl, r.cpu);
  EXPECT_GT(r.stats.lists.overflows, 0u);
  EXPECT_EQ(r.stats.lists.overflows, segment_list_stats(r.cpu).overflows);
}

TEST(GlSegmentListBuilder, ListCapacityOptionBoundsTheListsOnTheGpuOnly) {
  SL_REQUIRE_GL(ctx);
  GlBuilderOptions o;
  o.list_capacity = 4;
  GlSegmentListBuilder b(*ctx, o);
  const GlFixture& f = odd_fixture();
  const Camera cam = gl_perspective(vec3(100.0f, 70.0f, 150.0f), vec3(30.0f, 16.0f, 45.0f));
  const RayGenerator gen = make_ray_generator(cam, 61, 47);
  const auto order = build_visibility_order(f.tree, f.geometry, view_point(gen));
  SegmentListBuffer gl, bounded, exact;
  const GlBuildStats st = b.build_segment_lists(f.geometry, order, gen, gl);
  build_segment_lists_reference(f.geometry, order, gen, bounded, 0.0f, 4u);
  test::expect_same_lists(*ctx, gl, bounded);
  EXPECT_GT(st.lists.overflows, 0u);
  EXPECT_LE(st.lists.max_events, 4u);
  // Read back compactly: the events the lists hold, not pixels x capacity.
  EXPECT_EQ(gl.event_count, st.lists.events);
  EXPECT_LT(gl.event_count, std::size_t(61) * 47 * 4);
  const SegmentListStats e = build_segment_lists(f.geometry, order, gen, exact);  // the CPU: no capacity
  EXPECT_EQ(e.overflows, 0u);
  EXPECT_GT(e.max_events, 4u);
}

TEST(GlSegmentListBuilder, FallbackResolveRestoresScrambledFragmentOrder) {
  SL_REQUIRE_GL(ctx);
  GlBuilderOptions o;
  o.path = GlBuilderOptions::Path::Fallback;
  GlSegmentListBuilder b(*ctx, o);
  const GlFixture& f = odd_fixture();
  const Camera cams[] = {gl_perspective(vec3(100.0f, 70.0f, 150.0f), vec3(30.0f, 16.0f, 45.0f)),
                         gl_perspective(vec3(20.0f, 15.0f, 40.0f), vec3(50.0f, 16.0f, 10.0f), 90.0f)};
  std::mt19937 rng(1234);
  for (const Camera& cam : cams) {
    const RayGenerator gen = make_ray_generator(cam, 61, 47);
    const auto order = build_visibility_order(f.tree, f.geometry, view_point(gen));
    std::vector<std::uint32_t> perm(order.size());
    std::iota(perm.begin(), perm.end(), 0u);
    std::vector<std::uint32_t> reversed(perm.rbegin(), perm.rend());
    std::shuffle(perm.begin(), perm.end(), rng);
    SegmentListBuffer cpu, in_order, scrambled, backwards;
    build_segment_lists(f.geometry, order, gen, cpu);
    b.set_draw_order_for_testing({});
    b.build_segment_lists(f.geometry, order, gen, in_order);
    b.set_draw_order_for_testing(perm);
    const GlBuildStats st = b.build_segment_lists(f.geometry, order, gen, scrambled);
    b.set_draw_order_for_testing(reversed);
    b.build_segment_lists(f.geometry, order, gen, backwards);
    test::expect_same_lists(*ctx, in_order, cpu);
    test::expect_same_lists(*ctx, scrambled, cpu);
    test::expect_same_lists(*ctx, backwards, cpu);
    EXPECT_GT(st.records, 0u);
  }
  b.set_draw_order_for_testing({});
}

TEST(GlSegmentListBuilder, BandsAndPoolSplitsGiveTheSameLists) {
  SL_REQUIRE_GL(ctx);
  const GlFixture& f = odd_fixture();
  const Camera cam = gl_perspective(vec3(-40.0f, 20.0f, -30.0f), vec3(30.0f, 17.0f, 40.0f), 70.0f);
  GlBuilderOptions o;
  o.path = GlBuilderOptions::Path::Fallback;
  o.max_band_bytes = std::size_t(61) * 8 * kMaxEvents * sizeof(RayEvent);  // 8 rows per band
  GlSegmentListBuilder banded(*ctx, o);
  Built r = build_both(banded, f, cam, 61, 47);
  test::expect_same_lists(*ctx, r.gl, r.cpu);
  EXPECT_EQ(r.stats.bands, 6);  // 47 rows: 5 of 8, one of 7
  // A pool that holds the records of any 4-row band but not of a 24-row one: bands split until they
  // fit, and nothing is dropped.
  const std::vector<std::uint32_t> hits = hits_per_pixel(f, r);
  std::uint64_t worst4 = 0, total = 0;
  for (int y0 = 0; y0 < 47; y0 += 4) {
    const auto first = hits.begin() + std::ptrdiff_t(y0) * 61;
    const auto last = hits.begin() + std::ptrdiff_t(std::min(y0 + 4, 47)) * 61;
    worst4 = std::max<std::uint64_t>(worst4, std::accumulate(first, last, std::uint64_t(0)));
  }
  total = std::accumulate(hits.begin(), hits.end(), std::uint64_t(0));
  o.max_band_bytes = 0;
  o.max_record_bytes = worst4 * 12;
  GlSegmentListBuilder split(*ctx, o);
  r = build_both(split, f, cam, 61, 47);
  test::expect_same_lists(*ctx, r.gl, r.cpu);
  EXPECT_EQ(r.stats.records, total);
  EXPECT_GT(r.stats.redraws, 0u);
  EXPECT_GT(r.stats.bands, 1);
  EXPECT_EQ(r.stats.dropped_pixels, 0u);
}

TEST(GlSegmentListBuilder, RecordOverflowIsConservativeAndCounted) {
  SL_REQUIRE_GL(ctx);
  const GlFixture& f = odd_fixture();
  const Camera cam = gl_perspective(vec3(100.0f, 70.0f, 150.0f), vec3(30.0f, 16.0f, 45.0f));
  GlBuilderOptions o;
  o.path = GlBuilderOptions::Path::Fallback;
  o.max_records_per_pixel = 6;  // the resolve's sort array: deterministic per pixel
  GlSegmentListBuilder few(*ctx, o);
  Built r = build_both(few, f, cam, 61, 47);
  const std::vector<std::uint32_t> hits = hits_per_pixel(f, r);
  std::uint64_t expected_dropped = 0;
  for (std::size_t i = 0; i < hits.size(); ++i) {
    if (hits[i] > 6u) {
      ++expected_dropped;
      expect_conservative(r, i);
    } else {
      ASSERT_EQ(r.gl.counts[i], r.cpu.counts[i]) << test::describe_pixel(r.gl, i);
      for (std::uint32_t k = 0; k < r.cpu.count(i); ++k) {
        EXPECT_EQ(std::memcmp(&r.gl.list(i)[k], &r.cpu.list(i)[k], sizeof(RayEvent)), 0);
      }
    }
  }
  EXPECT_GT(expected_dropped, 0u);
  EXPECT_EQ(r.stats.dropped_pixels, expected_dropped);

  o.max_records_per_pixel = 512;
  o.max_record_bytes = 12 * 500;  // a pool far too small even for a 4-row band
  GlSegmentListBuilder tiny(*ctx, o);
  r = build_both(tiny, f, cam, 61, 47);
  EXPECT_GT(r.stats.dropped_pixels, 0u);
  std::uint64_t flagged = 0;
  for (std::size_t i = 0; i < r.cpu.counts.size(); ++i) {
    if (r.gl.counts[i] == r.cpu.counts[i]) continue;  // complete pixels equal the CPU's
    ++flagged;
    expect_conservative(r, i);
  }
  EXPECT_LE(flagged, r.stats.dropped_pixels);
}

TEST(GlSegmentListBuilder, EmptyOrderAndMissingVolumeGiveEmptyLists) {
  SL_REQUIRE_GL(ctx);
  GlSegmentListBuilder b(*ctx);
  const GlFixture& f = odd_fixture();
  const RayGenerator gen = make_ray_generator(gl_perspective(vec3(100.0f, 70.0f, 150.0f), vec3(30.0f, 16.0f, 45.0f)), 9, 7);
  SegmentListBuffer out;
  b.build_segment_lists(f.geometry, {}, gen, out);
  EXPECT_EQ(segment_list_stats(out).lists, 0u);
  // Looking away from the volume: every box lies behind the eye plane.
  const RayGenerator away = make_ray_generator(gl_perspective(vec3(100.0f, 70.0f, 150.0f), vec3(200.0f, 70.0f, 250.0f)), 9, 7);
  const auto order = build_visibility_order(f.tree, f.geometry, view_point(away));
  b.build_segment_lists(f.geometry, order, away, out);
  EXPECT_EQ(segment_list_stats(out).lists, 0u);
}

}  // namespace
}  // namespace sl
