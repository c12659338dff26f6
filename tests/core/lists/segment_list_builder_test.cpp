// The CPU tile builder (paper §7.3): equal to a brute-force per-pixel construction for perspective,
// orthographic and inside cameras and grazing rays, and for lists longer than its scratch; identical
// for any thread count; compact storage reused across frames; the 4-wide slab test against its scalar
// twin and intersect(); conservative screen rectangles; the bounding-geometry baseline.
#include "core/lists/segment_list_builder.h"

#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cstring>
#include <vector>

namespace sl {
namespace {

using C = OccupancyClass;

struct Fixture {
  OccupancyTree tree;
  OccupancyGeometry geometry;
};

Fixture random_fixture(std::uint64_t seed, int levels, ivec3 dims, vec3 spacing, std::size_t budget = 0) {
  const BlockGrid grid = make_block_grid(dims, spacing, 4);
  Fixture f{make_random_occupancy_tree(grid, seed, RandomTreeParams{levels, 0.75, 0.5}), {}};
  f.geometry = build_occupancy_geometry(f.tree, budget);
  return f;
}

// A random tree with a substantial geometry (a random root may stay unsplit).
Fixture rich_fixture(std::uint64_t seed, ivec3 dims, vec3 spacing, std::size_t budget = 0) {
  for (;; ++seed) {
    Fixture f = random_fixture(seed, 4, dims, spacing);
    if (f.geometry.boxes.size() < 40) continue;
    if (budget > 0) f.geometry = build_occupancy_geometry(f.tree, budget);
    return f;
  }
}

Camera perspective(vec3 eye, vec3 center, float fov = 40.0f) {
  Camera c;
  c.eye = eye;
  c.center = center;
  c.up = vec3(0.0f, 1.0f, 0.0f);
  c.fov_deg = fov;
  return c;
}

Camera orthographic(vec3 eye, vec3 center, float height) {
  Camera c = perspective(eye, center);
  c.projection = Projection::Orthographic;
  c.height = height;
  return c;
}

// Pixel-for-pixel equality of counts and events.
void expect_same_lists(const SegmentListBuffer& a, const SegmentListBuffer& b) {
  ASSERT_EQ(a.width, b.width);
  ASSERT_EQ(a.height, b.height);
  std::size_t differing = 0;
  for (std::size_t i = 0; i < a.counts.size(); ++i) {
    bool same = a.counts[i] == b.counts[i];
    for (std::uint32_t k = 0; same && k < a.count(i); ++k) {
      same = std::memcmp(&a.list(i)[k], &b.list(i)[k], sizeof(RayEvent)) == 0;
    }
    differing += same ? 0 : 1;
  }
  EXPECT_EQ(differing, 0u);
}

void check_against_reference(const Fixture& f, const Camera& cam, int w, int h, float eps) {
  const RayGenerator gen = make_ray_generator(cam, w, h);
  const auto order = build_visibility_order(f.tree, f.geometry, view_point(gen));
  SegmentListBuffer tiles, scalar, sse2, brute;
  const SegmentListStats s = build_segment_lists(f.geometry, order, gen, tiles, eps);  // 8 lanes with AVX2
  const SegmentListStats c = build_segment_lists(f.geometry, order, gen, scalar, eps, ListBuildPath::Scalar);
  const SegmentListStats q = build_segment_lists(f.geometry, order, gen, sse2, eps, ListBuildPath::Sse2);
  const SegmentListStats r = build_segment_lists_reference(f.geometry, order, gen, brute, eps);
  expect_same_lists(tiles, brute);
  expect_same_lists(scalar, brute);  // the fast paths' scalar twin (STYLE.md #15)
  expect_same_lists(sse2, brute);    // the four-lane path (Fast's without AVX2)
  EXPECT_EQ(s.slab_tests, c.slab_tests);
  EXPECT_EQ(q.slab_tests, c.slab_tests);
  EXPECT_EQ(s.events, r.events);
  EXPECT_EQ(s.segments, r.segments);
  EXPECT_EQ(s.max_events, r.max_events);
  EXPECT_EQ(s.overflows, 0u);
  EXPECT_GT(s.lists, 0u);
  EXPECT_GT(s.slab_tests, 0u);
}

TEST(SegmentListBuilder, TilesEqualBruteForcePerspective) {
  const Fixture f = rich_fixture(7, ivec3(64), vec3(1.0f));
  check_against_reference(f, perspective(vec3(90.0f, 70.0f, 110.0f), vec3(32.0f)), 53, 41, 0.0f);
  check_against_reference(f, perspective(vec3(-40.0f, 20.0f, -30.0f), vec3(30.0f, 35.0f, 28.0f), 70.0f), 40, 33, 0.5f);
}

TEST(SegmentListBuilder, TilesEqualBruteForceOrthographic) {
  const Fixture f = rich_fixture(11, ivec3(61, 64, 45), vec3(1.0f, 0.5f, 2.0f));
  check_against_reference(f, orthographic(vec3(100.0f, -50.0f, 80.0f), vec3(30.0f, 16.0f, 45.0f), 110.0f), 47, 35, 0.0f);
}

TEST(SegmentListBuilder, TilesEqualBruteForceCameraInside) {
  const Fixture f = rich_fixture(5, ivec3(64), vec3(1.0f));
  check_against_reference(f, perspective(vec3(20.0f, 30.0f, 40.0f), vec3(50.0f, 31.0f, 10.0f), 90.0f), 45, 37, 0.0f);
  check_against_reference(f, orthographic(vec3(20.0f, 30.0f, 40.0f), vec3(50.0f, 31.0f, 10.0f), 60.0f), 45, 37, 0.0f);
}

TEST(SegmentListBuilder, TilesEqualBruteForceGrazingFacesAndEdges) {
  // Volume [0,1]^3 with 16 blocks per axis. Orthographic, axis-aligned, 17x17 pixels of 1/16: ray
  // origins lie on block planes, so rays run along box faces and edges.
  const Fixture f = rich_fixture(3, ivec3(64), vec3(1.0f / 64.0f));
  check_against_reference(f, orthographic(vec3(0.5f, 0.5f, 3.0f), vec3(0.5f, 0.5f, 0.0f), 17.0f / 16.0f), 17, 17, 0.0f);
  // Perspective with the eye on split planes: the centre row and column of an odd image lie in them.
  check_against_reference(f, perspective(vec3(0.5f, 0.5f, 2.5f), vec3(0.5f, 0.5f, 0.0f), 35.0f), 33, 33, 0.0f);
  check_against_reference(f, perspective(vec3(0.25f, 0.5f, 0.5f), vec3(0.25f, 0.5f, -1.0f), 100.0f), 31, 31, 0.0f);
}

TEST(SegmentListBuilder, BudgetedGeometry) {
  const Fixture full = rich_fixture(9, ivec3(64), vec3(1.0f));
  const Fixture f = rich_fixture(9, ivec3(64), vec3(1.0f), full.geometry.boxes.size() / 2);
  EXPECT_TRUE(f.geometry.truncated);
  EXPECT_LE(f.geometry.boxes.size(), full.geometry.boxes.size() / 2);
  check_against_reference(f, perspective(vec3(80.0f, 90.0f, 100.0f), vec3(32.0f)), 40, 40, 0.0f);
}

// Blocks alternating EMPTY / NON_EMPTY along x: a ray along x crosses one leaf per block, so its list
// holds about one event per block — far more than the tile scratch starts with (32 per pixel).
Fixture striped_fixture(int blocks_x) {
  const BlockGrid grid = make_block_grid(ivec3(4 * blocks_x, 8, 8), vec3(1.0f), 4);
  std::vector<C> classes(grid.block_count());
  for (int z = 0; z < grid.blocks.z; ++z) {
    for (int y = 0; y < grid.blocks.y; ++y) {
      for (int x = 0; x < grid.blocks.x; ++x) {
        classes[grid.block_index(ivec3(x, y, z))] = x % 2 ? C::Empty : C::NonEmpty;
      }
    }
  }
  Fixture f{OccupancyTree::from_block_classes(grid, classes), {}};
  f.geometry = build_occupancy_geometry(f.tree);
  return f;
}

TEST(SegmentListBuilder, LongListsNeverOverflow) {
  const Fixture f = striped_fixture(150);
  const Camera cam = perspective(vec3(-40.0f, 5.0f, 6.0f), vec3(300.0f, 4.0f, 4.0f), 4.0f);
  const RayGenerator gen = make_ray_generator(cam, 37, 29);
  const auto order = build_visibility_order(f.tree, f.geometry, view_point(gen));
  SegmentListBuffer tiles, scalar, sse2, brute;
  const SegmentListStats s = build_segment_lists(f.geometry, order, gen, tiles);
  build_segment_lists(f.geometry, order, gen, scalar, 0.0f, ListBuildPath::Scalar);
  build_segment_lists(f.geometry, order, gen, sse2, 0.0f, ListBuildPath::Sse2);
  build_segment_lists_reference(f.geometry, order, gen, brute);
  expect_same_lists(tiles, brute);
  expect_same_lists(scalar, brute);
  expect_same_lists(sse2, brute);
  EXPECT_GT(s.max_events, 2u * kMaxEvents);  // the tile scratch grew (twice at least)
  EXPECT_EQ(s.overflows, 0u);
  EXPECT_EQ(s.events, tiles.event_count);
  // The reference bounded to a capacity, as the GL builder's lists are: open, conservative tails.
  SegmentListBuffer small;
  const SegmentListStats b = build_segment_lists_reference(f.geometry, order, gen, small, 0.0f, 5u);
  EXPECT_GT(b.overflows, 0u);
  EXPECT_LE(b.max_events, 5u);
  for (std::size_t i = 0; i < small.counts.size(); ++i) {
    if (!small.overflowed(i)) continue;
    EXPECT_NE(C(small.list(i)[small.count(i) - 1].cls), C::Empty);  // open tail sampled to the exit
  }
}

TEST(SegmentListBuilder, StorageIsCompactAndReusedAcrossFrames) {
  const Fixture f = rich_fixture(13, ivec3(64), vec3(1.0f));
  const RayGenerator big = make_ray_generator(perspective(vec3(90.0f, 70.0f, 110.0f), vec3(32.0f)), 80, 64);
  const RayGenerator small = make_ray_generator(perspective(vec3(90.0f, 70.0f, 110.0f), vec3(32.0f)), 40, 32);
  SegmentListBuffer b;
  const auto big_order = build_visibility_order(f.tree, f.geometry, view_point(big));
  const SegmentListStats first = build_segment_lists(f.geometry, big_order, big, b);
  EXPECT_EQ(b.event_count, first.events);
  EXPECT_GE(b.events.size(), first.events);
  EXPECT_LE(b.events.capacity(), first.events + first.events / 8 + 1) << "grown to what the frame needs";
  EXPECT_EQ(b.storage_bytes(), b.events.capacity() * sizeof(RayEvent) + 2u * 80u * 64u * 4u);
  const RayEvent* storage = b.events.data();
  const std::size_t capacity = b.events.capacity();
  for (int frame = 0; frame < 3; ++frame) {  // fewer events: nothing is allocated again
    const RayGenerator& gen = frame % 2 ? big : small;
    const auto order = build_visibility_order(f.tree, f.geometry, view_point(gen));
    const SegmentListStats s = build_segment_lists(f.geometry, order, gen, b);
    EXPECT_EQ(b.events.data(), storage);
    EXPECT_EQ(b.events.capacity(), capacity);
    EXPECT_EQ(b.event_count, s.events);
    SegmentListBuffer fresh;
    build_segment_lists_reference(f.geometry, order, gen, fresh);
    expect_same_lists(b, fresh);
  }
}

// The tile builder writes every pixel's offset and count word, the empty lists' too, instead of
// emptying the buffer first: whatever a reused buffer held (here garbage, and a view in which most
// tiles see no box) must not show through.
TEST(SegmentListBuilder, EveryPixelIsWrittenWhateverTheBufferHeld) {
  const Fixture f = rich_fixture(17, ivec3(64), vec3(1.0f));
  const RayGenerator gen = make_ray_generator(perspective(vec3(220.0f, 180.0f, 250.0f), vec3(32.0f), 20.0f), 70, 50);
  const auto order = build_visibility_order(f.tree, f.geometry, view_point(gen));
  SegmentListBuffer b, fresh;
  b.reset(70, 50);
  std::fill(b.counts.begin(), b.counts.end(), 0x7FFFFFFFu);
  std::fill(b.offsets.begin(), b.offsets.end(), 0xDEADBEEFu);
  build_segment_lists(f.geometry, order, gen, b);
  build_segment_lists_reference(f.geometry, order, gen, fresh);
  expect_same_lists(b, fresh);
  std::size_t empty = 0;
  for (std::size_t i = 0; i < b.counts.size(); ++i) {
    if (b.counts[i] == 0u) {
      ++empty;
      EXPECT_EQ(b.offsets[i], 0u);
    }
  }
  EXPECT_GT(empty, b.counts.size() / 4) << "a view with empty tiles and empty pixels in tiles with boxes";
  EXPECT_LT(empty, b.counts.size());
}

TEST(SegmentListBuilder, FixedCapacityListsAreCompacted) {  // the GL builder's read back
  const Fixture f = rich_fixture(17, ivec3(64), vec3(1.0f));
  const RayGenerator gen = make_ray_generator(perspective(vec3(90.0f, 70.0f, 110.0f), vec3(32.0f)), 37, 29);
  const auto order = build_visibility_order(f.tree, f.geometry, view_point(gen));
  constexpr std::uint32_t kCap = 6;
  SegmentListBuffer bounded;
  const SegmentListStats b = build_segment_lists_reference(f.geometry, order, gen, bounded, 0.0f, kCap);
  ASSERT_GT(b.overflows, 0u);
  // The fixed layout: pixel i's events at [i * kCap ...), garbage past its count.
  const std::size_t pixels = bounded.counts.size();
  std::vector<RayEvent> fixed(pixels * kCap, detail::make_event(-1.0f, EventType::Exit, C::Unknown));
  for (std::size_t i = 0; i < pixels; ++i) std::copy_n(bounded.list(i), bounded.count(i), fixed.data() + i * kCap);
  std::vector<std::uint32_t> words = bounded.counts;
  ASSERT_EQ(bounded.count(0), 0u);
  words[0] = kListOverflow;  // an empty list with the flag (the GL fallback's missed pixel) stays so
  SegmentListBuffer compact;
  const SegmentListStats c = compact_fixed_lists(fixed.data(), words.data(), kCap, gen.width, gen.height, compact);
  EXPECT_EQ(compact.counts[0], kListOverflow);
  compact.counts[0] = bounded.counts[0];
  expect_same_lists(compact, bounded);
  EXPECT_EQ(c.events, b.events);
  EXPECT_EQ(c.overflows, b.overflows);
  EXPECT_EQ(compact.event_count, b.events);
}

TEST(SegmentListBuilder, TileBuilderNeedsADepthFirstOrder) {
  const Fixture f = rich_fixture(7, ivec3(64), vec3(1.0f));
  const RayGenerator gen = make_ray_generator(perspective(vec3(90.0f, 70.0f, 110.0f), vec3(32.0f)), 20, 20);
  auto order = build_visibility_order(f.tree, f.geometry, view_point(gen));
  ASSERT_GE(order.size(), 4u);
  std::swap(order[order.size() - 1], order[order.size() - 2]);  // the root's BACK no longer closes it
  SegmentListBuffer b;
  EXPECT_THROW(build_segment_lists(f.geometry, order, gen, b), std::logic_error);
  order.pop_back();  // a box left open
  std::swap(order[order.size() - 1], order[order.size() - 2]);
  EXPECT_THROW(build_segment_lists(f.geometry, order, gen, b), std::logic_error);
}

// The 4-wide slab test and its scalar twin give intersect()'s hit decision and, on a hit, its t0 and t1 bit for bit
// (STYLE.md #15), lane for lane (and the 8-wide AVX2 one the twin's, where it runs) — including rays parallel to an
// axis, origins on a slab's plane, inside the box, and boxes of zero thickness. The slab properties' inputs from
// one seed: uniform floats, coordinates that snap to a few values (coincident planes and origins) and boxes, some
// of zero thickness.
struct SlabInputs {
  std::uint64_t st;
  std::uint64_t next() {
    st = st * 6364136223846793005ull + 1442695040888963407ull;
    return st >> 11;
  }
  float u(float a, float b) { return a + (b - a) * float(double(next()) * 0x1.0p-53); }
  float coord(float a, float b) {
    static constexpr float kGrid[] = {0.0f, 0.25f, 0.5f, 1.0f};
    return next() % 3 == 0 ? kGrid[next() % 4] : u(a, b);
  }
  Box3 box() {
    Box3 b;
    for (int a = 0; a < 3; ++a) {
      const float p = coord(-1, 1), q = next() % 8 == 0 ? p : coord(-1, 1);
      b.lo[a] = std::min(p, q);
      b.hi[a] = std::max(p, q);
    }
    return b;
  }
};

RC_GTEST_PROP(SegmentListBuilderProperty, Slab4EqualsIntersectLaneForLane, (std::uint64_t seed)) {
  SlabInputs in{seed};
  auto next = [&] { return in.next(); };
  auto u = [&](float a, float b) { return in.u(a, b); };
  auto coord = [&](float a, float b) { return in.coord(a, b); };
  const Box3 box = in.box();
  alignas(16) float o[3][8], inv[3][8];
  Ray rays[8];
  for (int k = 0; k < 8; ++k) {
    vec3 d;
    const bool aim = next() % 2 == 0;  // at a point of the box (or near it): hits are common
    for (int a = 0; a < 3; ++a) {
      rays[k].origin[a] = coord(-2, 2);
      d[a] = aim ? u(box.lo[a] - 0.1f, box.hi[a] + 0.1f) - rays[k].origin[a] : u(-1, 1);
      if (next() % 4 == 0) d[a] = next() % 4 == 0 ? -0.0f : 0.0f;
    }
    if (d == vec3(0.0f)) d.z = 1.0f;
    rays[k].dir = glm::normalize(d);
    for (int a = 0; a < 3; ++a) {
      if (d[a] == 0.0f) rays[k].dir[a] = d[a];  // keep the signed zero
      o[a][k] = rays[k].origin[a];
      inv[a][k] = detail::slab_reciprocal(rays[k].dir[a]);
    }
  }
  const float* const op[3] = {o[0], o[1], o[2]};
  const float* const ip[3] = {inv[0], inv[1], inv[2]};
  for (std::size_t i : {std::size_t(0), std::size_t(3), std::size_t(4)}) {  // aligned and unaligned lanes
    alignas(16) float s0[4], s1[4], v0[4], v1[4];
    const unsigned fast = detail::slab4<ListBuildPath::Fast>(op, ip, i, box, v0, v1);
    const unsigned scalar = detail::slab4<ListBuildPath::Scalar>(op, ip, i, box, s0, s1);
    RC_ASSERT(fast == scalar);
    RC_CLASSIFY(scalar != 0u, "some lane hits");
    for (int k = 0; k < 4; ++k) {
      const Interval iv = intersect(rays[i + std::size_t(k)], box);
      const bool hit = !iv.empty() && iv.t1 > 0.0f;
      RC_ASSERT(((scalar >> k) & 1u) == (hit ? 1u : 0u));
      RC_ASSERT(std::memcmp(&v0[k], &s0[k], 4) == 0);
      RC_ASSERT(std::memcmp(&v1[k], &s1[k], 4) == 0);
      if (hit) {
        RC_ASSERT(std::memcmp(&s0[k], &iv.t0, 4) == 0);
        RC_ASSERT(std::memcmp(&s1[k], &iv.t1, 4) == 0);
      }
    }
  }
  if (list_build_lanes8()) {  // the eight-lane (AVX2) test: both halves the four-lane twin's
    alignas(32) float e0[8], e1[8], s0[8], s1[8];
    const unsigned eight = detail::slab8(op, ip, 0, box, e0, e1);
    const unsigned lo = detail::slab4<ListBuildPath::Scalar>(op, ip, 0, box, s0, s1);
    const unsigned hi = detail::slab4<ListBuildPath::Scalar>(op, ip, 4, box, s0 + 4, s1 + 4);
    RC_ASSERT(eight == (lo | hi << 4));
    RC_ASSERT(std::memcmp(e0, s0, sizeof s0) == 0 && std::memcmp(e1, s1, sizeof s1) == 0);
  }
}

// Perspective rays share their origin: the Fast path's slab test with the box taken relative to it
// once (slab4_shared, both paths; slab8_shared with AVX2) is bit for bit slab4's on the same rays,
// lane for lane.
RC_GTEST_PROP(SegmentListBuilderProperty, Slab4SharedEqualsSlab4LaneForLane, (std::uint64_t seed)) {
  SlabInputs in{seed};
  auto next = [&] { return in.next(); };
  auto u = [&](float a, float b) { return in.u(a, b); };
  auto coord = [&](float a, float b) { return in.coord(a, b); };
  const Box3 box = in.box();
  const vec3 origin(coord(-2, 2), coord(-2, 2), coord(-2, 2));
  alignas(16) float o[3][8], inv[3][8];
  for (int k = 0; k < 8; ++k) {
    vec3 d;
    for (int a = 0; a < 3; ++a) {
      d[a] = next() % 2 == 0 ? u(box.lo[a] - 0.1f, box.hi[a] + 0.1f) - origin[a] : u(-1, 1);
      if (next() % 4 == 0) d[a] = next() % 4 == 0 ? -0.0f : 0.0f;
    }
    if (d == vec3(0.0f)) d.z = 1.0f;
    const vec3 n = glm::normalize(d);
    for (int a = 0; a < 3; ++a) {
      o[a][k] = origin[a];
      inv[a][k] = detail::slab_reciprocal(d[a] == 0.0f ? d[a] : n[a]);
    }
  }
  const float* const op[3] = {o[0], o[1], o[2]};
  const float* const ip[3] = {inv[0], inv[1], inv[2]};
  for (std::size_t i : {std::size_t(0), std::size_t(3), std::size_t(4)}) {
    alignas(16) float s0[4], s1[4], f0[4], f1[4], c0[4], c1[4];
    const unsigned ref = detail::slab4<ListBuildPath::Scalar>(op, ip, i, box, s0, s1);
    const unsigned fast = detail::slab4_shared<ListBuildPath::Fast>(ip, i, origin, box, f0, f1);
    const unsigned scalar = detail::slab4_shared<ListBuildPath::Scalar>(ip, i, origin, box, c0, c1);
    RC_ASSERT(fast == ref);
    RC_ASSERT(scalar == ref);
    RC_CLASSIFY(ref != 0u, "some lane hits");
    RC_ASSERT(std::memcmp(f0, s0, sizeof s0) == 0 && std::memcmp(f1, s1, sizeof s1) == 0);
    RC_ASSERT(std::memcmp(c0, s0, sizeof s0) == 0 && std::memcmp(c1, s1, sizeof s1) == 0);
  }
  if (list_build_lanes8()) {
    alignas(32) float e0[8], e1[8], s0[8], s1[8];
    const unsigned eight = detail::slab8_shared(ip, 0, origin, box, e0, e1);
    const unsigned lo = detail::slab4<ListBuildPath::Scalar>(op, ip, 0, box, s0, s1);
    const unsigned hi = detail::slab4<ListBuildPath::Scalar>(op, ip, 4, box, s0 + 4, s1 + 4);
    RC_ASSERT(eight == (lo | hi << 4));
    RC_ASSERT(std::memcmp(e0, s0, sizeof s0) == 0 && std::memcmp(e1, s1, sizeof s1) == 0);
  }
}

// The tile builder's (and the CPU cast's) rays are gen.ray()'s bit for bit (perspective and
// orthographic, a tile at the image's corner cut by both edges), zero past the edges.
TEST(SegmentListBuilder, TileRaysEqualRayGenerator) {
  constexpr int T = kTileSize;
  for (const Camera& cam : {perspective(vec3(90.0f, 70.0f, 110.0f), vec3(32.0f), 53.0f),
                            orthographic(vec3(100.0f, -50.0f, 80.0f), vec3(30.0f, 16.0f, 45.0f), 110.0f)}) {
    const RayGenerator gen = make_ray_generator(cam, 2 * T + 5, T + 3);
    for (const ScreenRect tile : {ScreenRect{T, 0, 2 * T - 1, T - 1}, ScreenRect{2 * T, T, 2 * T + 4, T + 2}}) {
      alignas(16) float origin[3][T * T], inv[3][T * T], dir[3][T * T], origin2[3][T * T], inv2[3][T * T];
      detail::tile_rays(gen, tile, origin, inv, dir);
      detail::tile_rays(gen, tile, origin2, inv2);  // without directions: the same origins and reciprocals
      EXPECT_EQ(std::memcmp(origin, origin2, sizeof origin), 0);
      EXPECT_EQ(std::memcmp(inv, inv2, sizeof inv), 0);
      for (int ly = 0; ly < T; ++ly) {
        for (int lx = 0; lx < T; ++lx) {
          const int k = ly * T + lx, x = tile.x0 + lx, y = tile.y0 + ly;
          for (int a = 0; a < 3; ++a) {
            if (x > tile.x1 || y > tile.y1) {
              EXPECT_EQ(origin[a][k], 0.0f);
              EXPECT_EQ(inv[a][k], 0.0f);
              EXPECT_EQ(dir[a][k], 0.0f);
              continue;
            }
            const Ray ray = gen.ray(x, y);
            const float r = detail::slab_reciprocal(ray.dir[a]);
            EXPECT_EQ(std::memcmp(&origin[a][k], &ray.origin[a], 4), 0) << x << "," << y << " axis " << a;
            EXPECT_EQ(std::memcmp(&inv[a][k], &r, 4), 0) << x << "," << y << " axis " << a;
            EXPECT_EQ(std::memcmp(&dir[a][k], &ray.dir[a], 4), 0) << x << "," << y << " axis " << a;
          }
        }
      }
    }
  }
}

TEST(SegmentListBuilder, AnyThreadCountGivesIdenticalLists) {
  const Fixture f = rich_fixture(21, ivec3(64, 60, 64), vec3(1.0f));
  const RayGenerator gen = make_ray_generator(perspective(vec3(90.0f, 20.0f, 120.0f), vec3(32.0f)), 97, 65);
  const auto order = build_visibility_order(f.tree, f.geometry, view_point(gen));
  SegmentListBuffer one, many;
  tbb::task_arena(1).execute([&] { build_segment_lists(f.geometry, order, gen, one, 0.3f); });
  tbb::task_arena(4).execute([&] { build_segment_lists(f.geometry, order, gen, many, 0.3f); });
  expect_same_lists(one, many);
}

TEST(SegmentListBuilder, RootOnlyTreeGivesOneUnknownSegmentPerRay) {  // DESIGN.md "Ray segment lists" default list
  const BlockGrid grid = make_block_grid(ivec3(30, 20, 10), vec3(1.0f), 8);
  const OccupancyTree t(grid);
  const OccupancyGeometry g = build_occupancy_geometry(t);
  const RayGenerator gen = make_ray_generator(perspective(vec3(15.0f, 10.0f, 60.0f), vec3(15.0f, 10.0f, 5.0f), 50.0f), 21, 15);
  const auto order = build_visibility_order(t, g, view_point(gen));
  SegmentListBuffer b;
  const SegmentListStats s = build_segment_lists(g, order, gen, b);
  EXPECT_EQ(s.segments, s.lists);
  EXPECT_EQ(s.max_events, 2u);
  const std::size_t centre = b.pixel(10, 7);
  ASSERT_EQ(b.count(centre), 2u);
  EXPECT_EQ(C(b.list(centre)[0].cls), C::Unknown);
  EXPECT_NEAR(b.list(centre)[0].t, 50.0f, 1e-4f);  // front face z = 10
  EXPECT_NEAR(b.list(centre)[1].t, 60.0f, 1e-4f);
  EXPECT_EQ(C(b.list(centre)[1].cls), C::Invalid);
  EXPECT_EQ(b.count(b.pixel(0, 0)), 0u);  // misses the volume
}

// Uniform floats in [a, b) from a 64-bit LCG seeded by a property's argument.
struct Uniform {
  std::uint64_t s;
  float operator()(float a, float b) {
    s = s * 6364136223846793005ull + 1442695040888963407ull;
    return a + (b - a) * float(double(s >> 11) * 0x1.0p-53);
  }
};

RC_GTEST_PROP(SegmentListBuilderProperty, ScreenRectContainsEveryHitPixel, (std::uint64_t seed, bool ortho)) {
  Uniform u{seed};
  const vec3 lo(u(-2, 2), u(-2, 2), u(-2, 2));
  const Box3 box{lo, lo + vec3(u(0.01f, 2), u(0.01f, 2), u(0.01f, 2))};
  const vec3 eye(u(-4, 4), u(-4, 4), u(-4, 4));
  const Camera cam = ortho ? orthographic(eye, vec3(u(-1, 1), u(-1, 1), u(-1, 1)), u(1, 6))
                           : perspective(eye, vec3(u(-1, 1), u(-1, 1), u(-1, 1)), u(20, 120));
  const int w = int(u(8, 40)), h = int(u(8, 40));
  const RayGenerator gen = make_ray_generator(cam, w, h);
  const ScreenRect r = conservative_screen_rect(box, gen);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const Interval iv = intersect(gen.ray(x, y), box);
      if (iv.empty() || !(iv.t1 > 0.0f)) continue;
      RC_ASSERT(!r.empty());
      RC_ASSERT(x >= r.x0 && x <= r.x1 && y >= r.y0 && y <= r.y1);
    }
  }
}

// The same at the sizes the renderer runs (256-4096 pixels a side), with boxes far away (a few pixels
// wide, where the rectangle's margin matters most), near, and seen from their faces' planes (grazing
// rays): every pixel whose ray hits the box lies in the rectangle. Checked on the rectangle grown by
// 8 pixels (where rounding could push a hit out) and at 512 random pixels anywhere.
RC_GTEST_PROP(SegmentListBuilderProperty, ScreenRectContainsEveryHitPixelLargeImages, (std::uint64_t seed, bool ortho)) {
  Uniform u{seed};
  const vec3 lo(u(-100, 100), u(-100, 100), u(-100, 100));
  const Box3 box{lo, lo + vec3(u(0.05f, 8), u(0.05f, 8), u(0.05f, 8))};
  const vec3 centre = 0.5f * (box.lo + box.hi);
  vec3 eye = centre + glm::normalize(vec3(u(-1, 1), u(-1, 1), u(-1, 1)) + vec3(1e-3f)) * u(2, 400);
  if (u(0, 1) < 0.4f) {  // in the plane of a face: rays graze it
    const int a = int(u(0, 2.99f));
    eye[a] = u(0, 1) < 0.5f ? box.lo[a] : box.hi[a];
  }
  const vec3 target = centre + vec3(u(-4, 4), u(-4, 4), u(-4, 4));
  const Camera cam = ortho ? orthographic(eye, target, u(1, 60)) : perspective(eye, target, u(5, 120));
  const int w = int(u(256, 4096)), h = int(u(256, 4096));
  const RayGenerator gen = make_ray_generator(cam, w, h);
  const ScreenRect r = conservative_screen_rect(box, gen);
  const auto check = [&](int x, int y) {
    const Interval iv = intersect(gen.ray(x, y), box);
    if (iv.empty() || !(iv.t1 > 0.0f)) return;
    RC_ASSERT(!r.empty());
    RC_ASSERT(x >= r.x0 && x <= r.x1 && y >= r.y0 && y <= r.y1);
  };
  if (!r.empty()) {
    const int x0 = std::max(r.x0 - 8, 0), x1 = std::min(r.x1 + 8, w - 1);
    const int y0 = std::max(r.y0 - 8, 0), y1 = std::min(r.y1 + 8, h - 1);
    if (std::int64_t(x1 - x0 + 1) * (y1 - y0 + 1) <= 4'000'000) {
      for (int y = y0; y <= y1; ++y)
        for (int x = x0; x <= x1; ++x) check(x, y);
    }
  }
  for (int i = 0; i < 512; ++i) check(int(u(0, float(w) - 0.01f)), int(u(0, float(h) - 0.01f)));
}

// The classes the lists from `f`'s geometry and from it flattened (flatten_sparse_subtrees) give each
// ray, compared at every event depth of either list, between every two consecutive ones and past the
// last.
struct ClassComparison {
  std::size_t compared = 0, differing = 0, overflows = 0;
  // Differing where the flattened class is not that of any leaf whose closed box holds the point: the
  // lists' contract for rays in split planes (RaysInSplitPlanesTakeAClassOfAnAdjacentLeaf).
  std::size_t unexplained = 0;
};
ClassComparison compare_flattened_classes(const Fixture& f, const RayGenerator& gen) {
  const OccupancyGeometry flat = flatten_sparse_subtrees(f.tree, f.geometry);
  SegmentListBuffer a, b;
  build_segment_lists(f.geometry, build_visibility_order(f.tree, f.geometry, view_point(gen)), gen, a);
  const SegmentListStats st = build_segment_lists(flat, build_visibility_order(f.tree, flat, view_point(gen)), gen, b);
  ClassComparison r;
  r.overflows = st.overflows;
  const std::vector<OccupancyBox> leaves = leaf_boxes(f.tree, f.geometry.depth_limit);
  // The class a list gives depth t: the class after its last event at or before t (Invalid before any).
  const auto class_at = [](const RayEvent* ev, std::uint32_t n, float t) {
    C c = C::Invalid;
    for (std::uint32_t k = 0; k < n && ev[k].t <= t; ++k) c = C(ev[k].cls);
    return c;
  };
  for (std::size_t p = 0; p < a.counts.size(); ++p) {
    std::vector<float> ts;
    for (std::uint32_t k = 0; k < a.count(p); ++k) ts.push_back(a.list(p)[k].t);
    for (std::uint32_t k = 0; k < b.count(p); ++k) ts.push_back(b.list(p)[k].t);
    std::sort(ts.begin(), ts.end());
    ts.erase(std::unique(ts.begin(), ts.end()), ts.end());
    for (std::size_t k = 0; k < ts.size(); ++k) {  // at each depth, and on to the next (past the last)
      for (const float t : {ts[k], k + 1 < ts.size() ? 0.5f * (ts[k] + ts[k + 1]) : ts[k] + 1.0f}) {
        const C ca = class_at(a.list(p), a.count(p), t), cb = class_at(b.list(p), b.count(p), t);
        ++r.compared;
        r.differing += ca != cb ? 1u : 0u;
        if (ca == cb) continue;
        const vec3 x = gen.ray(int(p % std::size_t(gen.width)), int(p / std::size_t(gen.width))).at(t);
        bool held = false;
        for (const OccupancyBox& leaf : leaves) held = held || (leaf.box.contains(x) && leaf.cls == cb);
        r.unexplained += held ? 0u : 1u;
      }
    }
  }
  return r;
}

// The lane paths (eight lanes where the host has AVX2, four, scalar) give the same lists, bit for
// bit, on random trees seen from anywhere — outside, inside, orthographic, at grazing angles along the
// axes (direction components of zero, whose slab reciprocals are infinite) — at image sizes whose rows
// end inside a group of lanes.
RC_GTEST_PROP(SegmentListBuilderProperty, EveryLanePathGivesTheSameLists, (std::uint64_t seed)) {
  Uniform u{seed};
  const Fixture f = rich_fixture(seed, ivec3(64), vec3(1.0f, 0.75f, 1.5f));
  const float pick = u(0, 1);
  vec3 eye = pick < 0.2f ? vec3(u(4, 60), u(4, 45), u(4, 90))  // inside the volume
                         : vec3(32.0f) + glm::normalize(vec3(u(-1, 1), u(-1, 1), u(-1, 1)) + vec3(1e-3f)) * u(70, 200);
  vec3 target(u(16, 48), u(16, 40), u(16, 80));
  if (pick > 0.85f) target = eye + vec3(u(0, 1) < 0.5f ? 50.0f : -50.0f, 0.0f, 0.0f);  // along an axis
  const Camera cam = u(0, 1) < 0.3f ? orthographic(eye, target, u(40, 120)) : perspective(eye, target, u(30, 90));
  const RayGenerator gen = make_ray_generator(cam, int(u(9, 70)), int(u(9, 50)));
  const auto order = build_visibility_order(f.tree, f.geometry, view_point(gen));
  SegmentListBuffer fast, sse2, scalar;
  const SegmentListStats a = build_segment_lists(f.geometry, order, gen, fast);
  const SegmentListStats b = build_segment_lists(f.geometry, order, gen, sse2, 0.0f, ListBuildPath::Sse2);
  const SegmentListStats c = build_segment_lists(f.geometry, order, gen, scalar, 0.0f, ListBuildPath::Scalar);
  RC_ASSERT(a.slab_tests == c.slab_tests);
  RC_ASSERT(b.slab_tests == c.slab_tests);
  RC_ASSERT(a.events == c.events);
  RC_ASSERT(b.events == c.events);
  for (std::size_t i = 0; i < scalar.counts.size(); ++i) {
    RC_ASSERT(fast.counts[i] == scalar.counts[i]);
    RC_ASSERT(sse2.counts[i] == scalar.counts[i]);
    if (scalar.count(i) == 0u) continue;  // a view may hold no events at all (no array to compare)
    RC_ASSERT(std::memcmp(fast.list(i), scalar.list(i), scalar.count(i) * sizeof(RayEvent)) == 0);
    RC_ASSERT(std::memcmp(sse2.list(i), scalar.list(i), scalar.count(i) * sizeof(RayEvent)) == 0);
  }
}

// Flattened lists give every ray the original's classes along its whole length: random trees,
// budgets, perspective, orthographic and inside cameras.
RC_GTEST_PROP(SegmentListBuilderProperty, FlattenedGeometryGivesEveryRayTheSameClasses, (std::uint64_t seed)) {
  Uniform u{seed};
  const std::size_t budget = u(0, 1) < 0.3f ? std::size_t(u(8, 60)) : 0u;
  const Fixture f = rich_fixture(seed, ivec3(64), vec3(1.0f), budget);
  const vec3 eye = u(0, 1) < 0.2f ? vec3(u(4, 60), u(4, 60), u(4, 60))  // inside the volume
                                  : vec3(32.0f) + glm::normalize(vec3(u(-1, 1), u(-1, 1), u(-1, 1)) + vec3(1e-3f)) * u(70, 200);
  const vec3 target(u(16, 48), u(16, 48), u(16, 48));
  const Camera cam = u(0, 1) < 0.3f ? orthographic(eye, target, u(40, 120)) : perspective(eye, target, u(30, 90));
  const ClassComparison r = compare_flattened_classes(f, make_ray_generator(cam, 41, 37));
  RC_ASSERT(r.compared > 0u);
  RC_ASSERT(r.differing == 0u);
  RC_ASSERT(r.overflows == 0u);
}

// Rays along box faces and edges (TilesEqualBruteForceGrazingFacesAndEdges' cameras) hit the boxes on
// both sides of a face, and which class the lists keep there depends on the boxes met: where the
// flattened lists differ, they keep the class of a leaf on one side, as the original's do (EMPTY is
// then conservative: the culling holds for the leaf's closed box).
TEST(SegmentListBuilder, FlattenedGeometryGivesGrazingRaysTheClassOfAnAdjacentLeaf) {
  std::size_t differing = 0;
  for (std::uint64_t seed : {3u, 8u, 21u}) {
    const Fixture f = rich_fixture(seed, ivec3(64), vec3(1.0f / 64.0f));
    const Camera cams[] = {orthographic(vec3(0.5f, 0.5f, 3.0f), vec3(0.5f, 0.5f, 0.0f), 17.0f / 16.0f),
                           perspective(vec3(0.5f, 0.5f, 2.5f), vec3(0.5f, 0.5f, 0.0f), 35.0f),
                           perspective(vec3(0.25f, 0.5f, 0.5f), vec3(0.25f, 0.5f, -1.0f), 100.0f)};
    const int sizes[] = {17, 33, 31};
    for (int i = 0; i < 3; ++i) {
      const ClassComparison r = compare_flattened_classes(f, make_ray_generator(cams[i], sizes[i], sizes[i]));
      EXPECT_GT(r.compared, 0u);
      EXPECT_EQ(r.unexplained, 0u) << "seed " << seed << ", camera " << i << ", differing " << r.differing;
      differing += r.differing;
    }
  }
  EXPECT_GT(differing, 0u);  // the cameras do graze faces where the two differ
}

TEST(SegmentListBuilder, BboxListsSpanFirstEntryToLastExitOfNonEmptyBoxes) {
  Fixture f;
  std::vector<OccupancyBox> leaves;
  for (std::uint64_t seed = 4;; ++seed) {  // a tree with both empty and non-empty leaves
    f = random_fixture(seed, 3, ivec3(32), vec3(1.0f));
    leaves = leaf_boxes(f.tree);
    const auto empty = std::count_if(leaves.begin(), leaves.end(), [](const auto& l) { return l.cls == C::Empty; });
    if (empty > 0 && empty < std::ptrdiff_t(leaves.size()) - 2) break;
  }
  const RayGenerator gen = make_ray_generator(perspective(vec3(50.0f, 40.0f, 70.0f), vec3(16.0f)), 31, 29);
  SegmentListBuffer b;
  const SegmentListStats s = build_bbox_lists(leaves, gen, b);
  EXPECT_EQ(s.max_events, 2u);
  EXPECT_GT(s.lists, 0u);
  for (int y = 0; y < gen.height; ++y) {
    for (int x = 0; x < gen.width; ++x) {
      const Ray ray = gen.ray(x, y);
      float first = HUGE_VALF, last = -HUGE_VALF;
      bool unknown = false;
      for (const OccupancyBox& l : leaves) {
        const Interval iv = intersect(ray, l.box);
        if (l.cls == C::Empty || iv.empty() || !(iv.t1 > 0.0f)) continue;
        first = std::min(first, std::max(iv.t0, 0.0f));
        last = std::max(last, iv.t1);
        unknown = unknown || l.cls == C::Unknown;
      }
      const std::size_t p = b.pixel(x, y);
      if (!(last > first)) {
        EXPECT_EQ(b.count(p), 0u);
        continue;
      }
      ASSERT_EQ(b.count(p), 2u);
      EXPECT_EQ(b.list(p)[0].t, first);
      EXPECT_EQ(b.list(p)[1].t, last);
      EXPECT_EQ(C(b.list(p)[0].cls), unknown ? C::Unknown : C::NonEmpty);
      EXPECT_EQ(C(b.list(p)[1].cls), C::Invalid);
    }
  }
}

}  // namespace
}  // namespace sl
