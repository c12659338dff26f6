// Ray events, merge rules (Alg. 5) and the main SparseLeap property (DESIGN.md "Ray segment lists", segment_rules.py):
// lists built in visibility order equal the classes of the leaves the ray crosses.
#include "core/lists/segment_list.h"

#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

#include "core/occupancy/occupancy_geometry.h"
#include "core/occupancy/occupancy_tree.h"
#include "core/util/rng.h"
#include "core/lists/visibility_order.h"

namespace sl {
namespace {

using C = OccupancyClass;
constexpr EventType kEntry = EventType::Entry;
constexpr EventType kExit = EventType::Exit;

struct Ev {
  float t;
  EventType type;
  C cls;
};

std::vector<Ev> events_of(const SegmentList& l) {
  std::vector<Ev> out;
  for (std::uint32_t i = 0; i < l.count(); ++i) {
    out.push_back({l.events[i].t, EventType(l.events[i].type), C(l.events[i].cls)});
  }
  return out;
}

void expect_list(const SegmentList& l, std::vector<std::pair<float, C>> want) {
  ASSERT_EQ(l.count(), want.size());
  for (std::size_t i = 0; i < want.size(); ++i) {
    EXPECT_EQ(l.events[i].t, want[i].first) << "event " << i;
    EXPECT_EQ(C(l.events[i].cls), want[i].second) << "event " << i;
  }
}

TEST(SegmentList, LayoutIsPlain) {
  static_assert(sizeof(RayEvent) == 8);
  static_assert(std::is_trivially_copyable_v<RayEvent>);
  static_assert(std::is_trivially_copyable_v<SegmentListView>);
  EXPECT_EQ(offsetof(RayEvent, t), 0u);
  EXPECT_EQ(offsetof(RayEvent, type), 4u);
  EXPECT_EQ(offsetof(RayEvent, cls), 5u);
}

TEST(SegmentList, Rule1SameTypeOverwritesKeepingTheLast) {  // Alg. 5, rule 1
  SegmentList l;
  l.add(1.0f, kEntry, C::Empty);
  l.add(1.0f, kEntry, C::NonEmpty);
  expect_list(l, {{1.0f, C::NonEmpty}});
  l.add(3.0f, kExit, C::Unknown);
  l.add(3.0f, kExit, C::Empty);
  expect_list(l, {{1.0f, C::NonEmpty}, {3.0f, C::Empty}});
}

TEST(SegmentList, Rule1DropsAnOverwriteEqualToThePreviousClass) {  // minimality (DESIGN.md "Ray segment lists")
  SegmentList l;
  l.add(0.0f, kEntry, C::NonEmpty);
  l.add(1.0f, kEntry, C::Empty);
  l.add(1.0f, kEntry, C::NonEmpty);
  expect_list(l, {{0.0f, C::NonEmpty}});
}

TEST(SegmentList, Rule2EntryThenExitDeletesBoth) {  // Alg. 5, rule 2
  SegmentList l;
  l.add(0.0f, kEntry, C::NonEmpty);
  l.add(2.0f, kEntry, C::Unknown);
  l.add(2.0f, kExit, C::Empty);
  expect_list(l, {{0.0f, C::NonEmpty}});
}

TEST(SegmentList, Rule3ExitThenEntryBackToTheSameClassDeletesBoth) {  // Alg. 5, rule 3
  SegmentList l;
  l.add(0.0f, kEntry, C::NonEmpty);
  l.add(1.0f, kEntry, C::Empty);
  l.add(2.0f, kExit, C::NonEmpty);
  l.add(2.0f, kEntry, C::Empty);  // the next sibling is EMPTY again: one long EMPTY segment
  expect_list(l, {{0.0f, C::NonEmpty}, {1.0f, C::Empty}});
  // EXIT then ENTRY to a different class is kept (as in segment_rules.py: the zero-length segment
  // between them is harmless).
  l.add(3.0f, kExit, C::NonEmpty);
  l.add(3.0f, kEntry, C::Unknown);
  expect_list(l, {{0.0f, C::NonEmpty}, {1.0f, C::Empty}, {3.0f, C::NonEmpty}, {3.0f, C::Unknown}});
}

TEST(SegmentList, NoOpEventsAreDropped) {
  SegmentList l;
  l.add(0.0f, kEntry, C::Empty);
  l.add(1.0f, kEntry, C::Empty);
  l.add(2.0f, kExit, C::Empty);
  expect_list(l, {{0.0f, C::Empty}});
}

TEST(SegmentList, EarlierEventIsTreatedAsCoincident) {  // monotonicity guard
  SegmentList l;
  l.add(0.0f, kEntry, C::NonEmpty);
  l.add(2.0f, kEntry, C::Empty);
  l.add(1.5f, kEntry, C::Unknown);  // rounding: arrives "before" the tail -> same depth, rule 1
  expect_list(l, {{0.0f, C::NonEmpty}, {2.0f, C::Unknown}});
}

TEST(SegmentList, ShortEmptyGapIsAbsorbedIntoTheFollowingSegment) {
  SegmentList l;
  l.add(0.0f, kEntry, C::NonEmpty, 0.1f);
  l.add(1.0f, kEntry, C::Empty, 0.1f);
  l.add(1.05f, kEntry, C::Unknown, 0.1f);  // EMPTY [1, 1.05) is too short: UNKNOWN starts at 1
  expect_list(l, {{0.0f, C::NonEmpty}, {1.0f, C::Unknown}});
  l.add(2.0f, kExit, C::Empty, 0.1f);
  l.add(2.05f, kEntry, C::NonEmpty, 0.1f);  // absorbed and merged with nothing (previous is UNKNOWN)
  expect_list(l, {{0.0f, C::NonEmpty}, {1.0f, C::Unknown}, {2.0f, C::NonEmpty}});
  l.add(3.0f, kEntry, C::Empty, 0.1f);
  l.add(3.2f, kExit, C::NonEmpty, 0.1f);  // long enough: kept
  expect_list(l, {{0.0f, C::NonEmpty}, {1.0f, C::Unknown}, {2.0f, C::NonEmpty}, {3.0f, C::Empty}, {3.2f, C::NonEmpty}});
}

TEST(SegmentList, ShortGapMergesWithTheSegmentBefore) {
  SegmentList l;
  l.add(0.0f, kEntry, C::NonEmpty, 0.1f);
  l.add(1.0f, kEntry, C::Empty, 0.1f);
  l.add(1.05f, kExit, C::NonEmpty, 0.1f);
  expect_list(l, {{0.0f, C::NonEmpty}});
}

TEST(SegmentList, ShortGapAppliesAfterASameDepthOverwrite) {
  SegmentList l;
  l.add(0.0f, kEntry, C::Unknown, 0.1f);
  l.add(1.0f, kEntry, C::Empty, 0.1f);
  l.add(1.05f, kEntry, C::Empty, 0.1f);     // no-op
  l.add(1.05f, kExit, C::Invalid, 0.1f);   // INVALID is not sampled: the gap stays EMPTY
  expect_list(l, {{0.0f, C::Unknown}, {1.0f, C::Empty}, {1.05f, C::Invalid}});
  SegmentList m;
  m.add(0.0f, kEntry, C::Unknown, 0.1f);
  m.add(1.0f, kEntry, C::Empty, 0.1f);
  m.add(1.05f, kEntry, C::Empty, 0.1f);
  m.add(1.5f, kEntry, C::Empty, 0.1f);
  expect_list(m, {{0.0f, C::Unknown}, {1.0f, C::Empty}});
}

TEST(SegmentList, ShortGapNeverMakesAnythingEmpty) {
  SegmentList l;
  l.add(0.0f, kEntry, C::Empty, 0.1f);
  l.add(0.05f, kEntry, C::NonEmpty, 0.1f);  // leading short EMPTY: NON_EMPTY starts at the entry
  l.add(1.0f, kEntry, C::Empty, 0.1f);
  l.add(1.01f, kExit, C::Invalid, 0.1f);
  expect_list(l, {{0.0f, C::NonEmpty}, {1.0f, C::Empty}, {1.01f, C::Invalid}});
}

TEST(SegmentList, OverflowKeepsTheTailConservative) {
  RayEvent ev[4];
  std::uint32_t count = 0;
  float t_seen = kNoEventYet;
  const C seq[] = {C::NonEmpty, C::Empty, C::Unknown, C::Empty, C::NonEmpty, C::Empty};
  for (int i = 0; i < 6; ++i) add_event(ev, count, t_seen, 4, float(i), kEntry, seq[i], 0.0f);
  EXPECT_TRUE(count & kListOverflow);
  EXPECT_EQ(count & kListCountMask, 4u);
  EXPECT_EQ(C(ev[3].cls), C::NonEmpty);  // was EMPTY; now extends to the volume exit
  EXPECT_EQ(segment_count(ev, 4), 4u);   // open list: last segment to the exit
  const RaySegment s = list_segment(ev, 4, 3, 10.0f);
  EXPECT_EQ(s.t0, 3.0f);
  EXPECT_EQ(s.t1, 10.0f);
  add_event(ev, count, t_seen, 4, 7.0f, kExit, C::Invalid, 0.0f);  // dropped
  EXPECT_EQ(count & kListCountMask, 4u);
}

TEST(SegmentList, BoxEventsFollowTheSlabTest) {
  SegmentList l;
  const Ray r{vec3(0.5f, 0.5f, 0.5f), vec3(0, 0, 1)};
  const Box3 holding{vec3(0.0f), vec3(1.0f)};
  const Box3 behind{vec3(0, 0, -2), vec3(1, 1, -1)};
  const Box3 missed{vec3(0.5f, 1.0f, 2.0f), vec3(2.0f, 2.0f, 3.0f)};
  l.add_box(r, behind, true, C::NonEmpty, C::Invalid, 0.0f);
  l.add_box(r, behind, false, C::NonEmpty, C::Invalid, 0.0f);
  EXPECT_EQ(l.count(), 0u);
  l.add_box(r, holding, true, C::NonEmpty, C::Invalid, 0.0f);
  l.add_box(r, missed, true, C::Empty, C::NonEmpty, 0.0f);
  l.add_box(r, holding, false, C::NonEmpty, C::Invalid, 0.0f);
  expect_list(l, {{0.0f, C::NonEmpty}, {0.5f, C::Invalid}});
  // Slabs are inclusive: a ray running along a box edge (zero direction component) hits the box.
  const Ray edge{vec3(1.0f, 1.0f, -1.0f), vec3(0, 0, 1)};
  EXPECT_FALSE(intersect(edge, holding).empty());
}

TEST(SegmentList, BufferAndViewAddressCompactLists) {
  SegmentListBuffer b;
  b.reset(3, 2);
  EXPECT_EQ(b.offsets.size(), 6u);
  EXPECT_EQ(b.count(0), 0u);
  // Pixel 5's two events stored first, then pixel 1's one: lists lie in any order of the pixels.
  SegmentList l5, l1;
  l5.add(1.0f, kEntry, C::Unknown);
  l5.add(2.0f, kExit, C::Invalid);
  l1.add(0.5f, kEntry, C::NonEmpty);
  b.events.assign(l5.events, l5.events + 2);
  b.events.push_back(l1.events[0]);
  b.event_count = 3;
  b.offsets[5] = 0;
  b.counts[5] = l5.count_word;
  b.offsets[1] = 2;
  b.counts[1] = 1u | kListOverflow;
  const SegmentListView v = b.view();
  EXPECT_EQ(v.event_count, 3u);
  EXPECT_EQ(v.count(5), 2u);
  EXPECT_FALSE(v.overflowed(5));
  EXPECT_EQ(v.list(5), b.events.data());
  EXPECT_EQ(C(v.list(5)[0].cls), C::Unknown);
  EXPECT_EQ(segment_count(v.list(5), v.count(5)), 1u);
  EXPECT_EQ(v.count(1), 1u);
  EXPECT_TRUE(v.overflowed(1));
  EXPECT_EQ(v.list(1), b.events.data() + 2);
  EXPECT_EQ(segment_count(v.list(1), v.count(1)), 1u);  // open: its segment runs to the volume exit
  EXPECT_EQ(v.count(0), 0u);
  EXPECT_EQ(b.storage_bytes(), b.events.capacity() * sizeof(RayEvent) + 12u * 4u);
  // A copy (as a device receives it) addresses the same lists.
  SegmentListBuffer c;
  c.assign(v);
  EXPECT_EQ(c.event_count, 3u);
  EXPECT_EQ(c.offsets, b.offsets);
  EXPECT_EQ(c.counts, b.counts);
  EXPECT_EQ(std::memcmp(c.events.data(), b.events.data(), 3 * sizeof(RayEvent)), 0);
  // reset empties every list and keeps the storage.
  const RayEvent* storage = b.events.data();
  b.reset(2, 2);
  EXPECT_EQ(b.event_count, 0u);
  EXPECT_EQ(b.count(3), 0u);
  EXPECT_EQ(b.events.data(), storage);
}

// ---- the SparseLeap property over random trees and rays (segment_rules.py, C++ edition) ----

struct Rng {
  SplitMix64 g;
  std::uint64_t next() { return g.next(); }
  float uniform(float a, float b) { return a + (b - a) * float(g.uniform_double()); }
  int range(int a, int b) { return a + int(next() % std::uint64_t(b - a + 1)); }
  bool coin(double p) { return g.uniform_double() < p; }
};

struct Scene {
  BlockGrid grid;
  OccupancyTree tree;
  OccupancyGeometry geometry;
  std::vector<OccupancyBox> leaves;
};

// A random tree like segment_rules.py's, over a unit cube or over a non-power-of-two, anisotropic grid
// (clipped boxes), optionally with a box budget (conservative cut).
Scene random_scene(Rng& rng, bool allow_budget) {
  const int levels = rng.range(1, 4);
  const int block = 4;
  ivec3 dims(block << levels);
  vec3 spacing(1.0f / float(block << levels));
  if (rng.coin(0.5)) {
    const int full = block << levels, half = block << (levels - 1);
    for (int a = 0; a < 3; ++a) dims[a] = rng.range(half + 1, full);
    dims[rng.range(0, 2)] = full;
    for (int a = 0; a < 3; ++a) spacing[a] = rng.uniform(0.5f, 2.0f);
  }
  Scene s{make_block_grid(dims, spacing, block), {}, {}, {}};
  s.tree = make_random_occupancy_tree(s.grid, rng.next(), RandomTreeParams{levels, 0.7, 0.6});
  const std::size_t budget = allow_budget && rng.coin(0.3) ? std::size_t(rng.range(1, 40)) : 0u;
  s.geometry = build_occupancy_geometry(s.tree, budget);
  s.leaves = leaf_boxes(s.tree, s.geometry.depth_limit);
  return s;
}

SegmentList ray_list(const Scene& s, const std::vector<VisibilityEntry>& order, const Ray& ray, float eps) {
  SegmentList l;
  for (const VisibilityEntry& e : order) {
    const OccupancyBox& b = s.geometry.boxes[e.box];
    l.add_box(ray, b.box, e.face == Face::Front, b.cls, b.parent_cls, eps);
  }
  return l;
}

struct Span {
  float t0, t1;
  C cls;
};

// Brute force: the leaves the ray crosses (t > 0), front to back.
std::vector<Span> leaf_spans(const Scene& s, const Ray& ray) {
  std::vector<Span> spans;
  for (const OccupancyBox& b : s.leaves) {
    const Interval iv = intersect(ray, b.box);
    if (iv.empty() || !(iv.t1 > 0.0f)) continue;
    spans.push_back({std::max(iv.t0, 0.0f), iv.t1, b.cls});
  }
  std::sort(spans.begin(), spans.end(), [](const Span& a, const Span& b) { return a.t0 < b.t0; });
  return spans;
}

// The list the leaves imply: one event per class change, then INVALID at the exit.
std::vector<Ev> expected_events(const std::vector<Span>& spans) {
  std::vector<Ev> out;
  for (const Span& sp : spans) {
    if (out.empty() || out.back().cls != sp.cls) out.push_back({sp.t0, kEntry, sp.cls});
  }
  if (!spans.empty()) out.push_back({spans.back().t1, kExit, C::Invalid});
  return out;
}

vec3 random_point_in(Rng& rng, const BlockGrid& g, bool snap) {
  vec3 p;
  for (int a = 0; a < 3; ++a) {
    if (snap) {  // rays through grid lines and corners: a block-plane coordinate
      p[a] = g.plane(a, std::min(g.block * rng.range(0, g.blocks[a]), g.dims[a]));
    } else {
      p[a] = rng.uniform(0.0f, float(g.dims[a]) * g.spacing[a]);
    }
  }
  return p;
}

vec3 random_eye(Rng& rng, const BlockGrid& g, bool inside) {
  const vec3 ext = g.volume_box().hi;
  if (inside) {
    return vec3(rng.uniform(0.05f, 0.95f), rng.uniform(0.05f, 0.95f), rng.uniform(0.05f, 0.95f)) * ext;
  }
  for (;;) {
    const vec3 e = vec3(rng.uniform(-1.5f, 2.5f), rng.uniform(-1.5f, 2.5f), rng.uniform(-1.5f, 2.5f)) * ext;
    if (!g.volume_box().contains(e)) return e;
  }
}

// The segments a caster sees: zero-length segments dropped (Alg. 5 rule 3 keeps one where an EXIT
// and an ENTRY of a different class meet at one depth, as segment_rules.py does), classes merged.
std::vector<Ev> visible_events(const std::vector<Ev>& ev, int* zero_length = nullptr) {
  std::vector<Ev> out;
  for (std::size_t i = 0; i < ev.size(); ++i) {
    if (i + 1 < ev.size() && ev[i].t == ev[i + 1].t) {
      if (zero_length) ++*zero_length;
      continue;
    }
    if (out.empty() || out.back().cls != ev[i].cls) out.push_back(ev[i]);
  }
  return out;
}

// With the short-gap rule off: the list is exactly the leaf classes the ray crosses.
void check_exact(const Scene& s, const std::vector<VisibilityEntry>& order, const Ray& ray, float scale) {
  const SegmentList l = ray_list(s, order, ray, 0.0f);
  const std::vector<Ev> want = expected_events(leaf_spans(s, ray));
  const std::vector<Ev> raw = events_of(l);
  RC_ASSERT(!l.overflowed());
  for (std::size_t i = 1; i < raw.size(); ++i) {
    RC_ASSERT(raw[i].cls != raw[i - 1].cls);  // minimal: no two adjacent segments of one class
    RC_ASSERT(raw[i].t >= raw[i - 1].t);      // front to back
  }
  if (!raw.empty()) RC_ASSERT(raw.back().cls == C::Invalid);
  const std::vector<Ev> got = visible_events(raw);
  RC_ASSERT(got.size() == want.size());
  for (std::size_t i = 0; i < got.size(); ++i) {
    RC_ASSERT(got[i].cls == want[i].cls);
    RC_ASSERT(std::abs(got[i].t - want[i].t) <= 1e-5f * (std::abs(want[i].t) + scale));
  }
}

// With eps > 0: EMPTY only where the leaves are EMPTY, and no short EMPTY before a sampled segment.
void check_conservative(const Scene& s, const std::vector<VisibilityEntry>& order, const Ray& ray, float eps,
                        float scale) {
  const SegmentList l = ray_list(s, order, ray, eps);
  const std::vector<Span> spans = leaf_spans(s, ray);
  const std::vector<Ev> got = events_of(l);
  RC_ASSERT(got.empty() == spans.empty());
  if (got.empty()) return;
  const float tol = 1e-5f * (std::abs(spans.back().t1) + scale);
  RC_ASSERT(got.back().cls == C::Invalid);
  RC_ASSERT(std::abs(got.front().t - spans.front().t0) <= tol);
  RC_ASSERT(std::abs(got.back().t - spans.back().t1) <= tol);
  for (std::size_t i = 0; i + 1 < got.size(); ++i) {
    if (got[i].cls != C::Empty) continue;
    for (const Span& sp : spans) {  // every leaf overlapping the EMPTY span is EMPTY
      const float overlap = std::min(sp.t1, got[i + 1].t) - std::max(sp.t0, got[i].t);
      if (overlap > tol) RC_ASSERT(sp.cls == C::Empty);
    }
    if (needs_sampling(got[i + 1].cls)) RC_ASSERT(got[i + 1].t - got[i].t >= eps);
  }
}

void run_property(bool inside, bool orthographic) {
  Rng rng{SplitMix64(*rc::gen::arbitrary<std::uint64_t>())};
  const Scene s = random_scene(rng, true);
  const Box3 vb = s.grid.volume_box();
  const float scale = glm::length(vb.hi);
  const vec3 eye = random_eye(rng, s.grid, inside);
  const vec3 dir = glm::normalize(random_point_in(rng, s.grid, false) - eye);
  const ViewPoint view{eye, dir, orthographic};
  const std::vector<VisibilityEntry> order = build_visibility_order(s.tree, s.geometry, view);
  for (int k = 0; k < 200; ++k) {
    Ray ray;
    if (orthographic) {  // parallel rays, origins on the plane through the eye
      const vec3 target = random_point_in(rng, s.grid, rng.coin(0.3));
      ray.dir = dir;
      ray.origin = target - glm::dot(target - eye, dir) * dir;
    } else {
      ray.origin = eye;
      ray.dir = glm::normalize(random_point_in(rng, s.grid, rng.coin(0.3)) - eye);
    }
    check_exact(s, order, ray, scale);
    check_conservative(s, order, ray, rng.uniform(0.0f, 0.3f) * scale, scale);
  }
}

// Rays lying exactly in split planes (the eye on a block plane, e.g. the centre column of an odd-sized
// image): both sides of the plane are hit, so the leaf truth is ambiguous; every span must take the
// class of a leaf whose closed box holds it (EMPTY is then conservative under the culling model).
RC_GTEST_PROP(SegmentListProperty, RaysInSplitPlanesTakeAClassOfAnAdjacentLeaf, ()) {
  Rng rng{SplitMix64(*rc::gen::arbitrary<std::uint64_t>())};
  const Scene s = random_scene(rng, true);
  const float scale = glm::length(s.grid.volume_box().hi);
  const bool inside = rng.coin(0.5);
  for (int k = 0; k < 50; ++k) {
    vec3 a = random_point_in(rng, s.grid, true);
    vec3 eye = inside ? random_eye(rng, s.grid, true) : a;
    const int axis = rng.range(0, 2);
    if (inside) {
      eye[axis] = a[axis];  // in the plane through a
    } else {
      eye[axis] = -0.5f * s.grid.volume_box().hi[axis];
    }
    vec3 b = random_point_in(rng, s.grid, true);
    const int axis2 = rng.range(0, 2);
    if (axis2 != axis) b[axis2] = eye[axis2];
    const vec3 d = b - eye;
    if (!(glm::length(d) > 0.0f)) continue;
    const Ray ray{eye, glm::normalize(d)};
    const auto order = build_visibility_order(s.tree, s.geometry, ViewPoint{eye, ray.dir, false});
    const std::vector<Ev> ev = events_of(ray_list(s, order, ray, 0.0f));
    for (std::size_t i = 0; i + 1 < ev.size(); ++i) {
      RC_ASSERT(ev[i + 1].t >= ev[i].t);
      if (!(ev[i + 1].t - ev[i].t > 1e-5f * scale)) continue;  // rounding slivers at corners
      for (float f : {0.2371f, 0.5113f, 0.7719f}) {
        const vec3 p = ray.at(ev[i].t + f * (ev[i + 1].t - ev[i].t));
        bool found = false;
        for (const OccupancyBox& leaf : s.leaves) found = found || (leaf.box.contains(p) && leaf.cls == ev[i].cls);
        RC_ASSERT(found);
      }
    }
  }
}

RC_GTEST_PROP(SegmentListProperty, ListEqualsLeafClassesCameraOutside, ()) { run_property(false, false); }
RC_GTEST_PROP(SegmentListProperty, ListEqualsLeafClassesCameraInside, ()) { run_property(true, false); }
RC_GTEST_PROP(SegmentListProperty, ListEqualsLeafClassesOrthographic, ()) { run_property(*rc::gen::arbitrary<bool>(), true); }

}  // namespace
}  // namespace sl
