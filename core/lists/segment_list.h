// Ray events and per-pixel ray segment lists (paper §7, Alg. 4-5; DESIGN.md "Ray segment lists"). Shared by the CPU
// builder, the CUDA caster and (mirrored line by line) the GL fragment shader: keep it plain.
//
// A list is a front-to-back sequence of events; segment i is [events[i].t, events[i+1].t) with class
// events[i].cls. A complete list ends with an event of class INVALID (the volume exit). A list whose
// last event is not INVALID overflowed: its last segment extends to the volume exit. The CPU builders
// never overflow (their lists are stored compactly, SegmentListBuffer); fixed-capacity lists (the GL
// builder's, a SegmentList held by value) can.
#pragma once

#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <vector>

#include "core/util/config.h"
#include "core/occupancy/occupancy_class.h"
#include "core/util/ray.h"

namespace sl {

enum class EventType : std::uint8_t { Entry = 0, Exit = 1 };

struct RayEvent {
  float t;             // ray parameter (world distance along the normalised direction)
  std::uint8_t type;   // EventType
  std::uint8_t cls;    // OccupancyClass of the segment that starts here
  std::uint16_t pad;
};
static_assert(sizeof(RayEvent) == 8 && offsetof(RayEvent, type) == 4 && offsetof(RayEvent, cls) == 5,
              "RayEvent layout (mirrored by the GL shader, packed by make_event)");
#if !defined(__CUDA_ARCH__)
static_assert(std::endian::native == std::endian::little, "make_event packs RayEvent little-endian");
#endif

inline constexpr std::uint32_t kMaxEvents = 64;            // capacity of SegmentList and of GL lists at most
inline constexpr std::uint32_t kListOverflow = 0x80000000u;  // flag bit in a list's count word
inline constexpr std::uint32_t kListCountMask = 0x7FFFFFFFu;

namespace detail {

// The event as one 64-bit word (t's bits, then type, class and a zero pad; x86-64 and CUDA devices are
// little-endian): member by member, GCC assembles the struct with a dozen masks per event, in the
// CPU builder's innermost loop.
SL_HOST_DEVICE inline RayEvent make_event(float t, EventType type, OccupancyClass cls) {
  std::uint32_t t_bits;
  std::memcpy(&t_bits, &t, sizeof t_bits);
  const std::uint64_t word =
      std::uint64_t(t_bits) | std::uint64_t(std::uint8_t(type)) << 32 | std::uint64_t(std::uint8_t(cls)) << 40;
  RayEvent e;
  std::memcpy(&e, &word, sizeof e);
  return e;
}

// Short-gap rule, conservative form (Alg. 5 lines 16-25 as DESIGN.md "Ray segment lists" allows them): `next` starts a
// NON_EMPTY/UNKNOWN segment at next.t; if the segment before it, [ev[n-1].t, next.t), is EMPTY and
// shorter than eps, that EMPTY segment is absorbed: the non-empty segment starts at ev[n-1].t instead.
// Never turns anything non-empty or unknown into EMPTY. Returns the new count, or 0xFFFFFFFF when
// the rule does not apply.
SL_HOST_DEVICE inline std::uint32_t absorb_short_gap(RayEvent* ev, std::uint32_t n, const RayEvent& next, float eps) {
  if (!(eps > 0.0f) || n == 0u || !needs_sampling(OccupancyClass(next.cls))) return 0xFFFFFFFFu;
  RayEvent& gap = ev[n - 1];
  if (gap.cls != std::uint8_t(OccupancyClass::Empty) || !(next.t - gap.t < eps)) return 0xFFFFFFFFu;
  gap.cls = next.cls;
  gap.type = next.type;
  if (n >= 2u && ev[n - 2].cls == gap.cls) --n;  // now continues the segment before: drop it
  return n;
}

}  // namespace detail

inline constexpr float kNoEventYet = -3.402823466e+38f;  // initial value of a list's t_seen

// Adds one event to the list tail (events[0..count), count word with the overflow flag), applying the
// merge rules of Alg. 5 exactly as segment_rules.py's add_event, then the conservative short-gap rule
// when eps > 0. `capacity`: the room at `ev` (a list that needs more overflows). `t_seen` is builder
// state per list (start: kNoEventYet): the largest depth seen so far.
SL_HOST_DEVICE inline void add_event(RayEvent* ev, std::uint32_t& count_word, float& t_seen, std::uint32_t capacity,
                                     float t, EventType type, OccupancyClass cls, float eps) {
  if (count_word & kListOverflow) return;  // overflowed: the tail is already conservative
  std::uint32_t n = count_word;
  // Monotonicity guard (not in the paper): events arrive front to back, so an earlier t can only come
  // from rounding or from a ray lying in a face shared by two sibling boxes (both are hit over the same
  // interval; the one visited second arrives "early"). Such an event is coincident with the latest
  // depth seen. Clamping to the tail's t is not enough: rules 2 and 3 pop events, after which the tail
  // lies earlier than events already merged, and an early event would then open a wrong segment.
  if (t < t_seen) {
    t = t_seen;
  } else {
    t_seen = t;
  }
  const std::uint8_t e_type = std::uint8_t(type), e_cls = std::uint8_t(cls);
  if (n > 0u && ev[n - 1].t == t) {  // isEqual(eventPrev.depth, depth): the same-depth rules
    RayEvent& prev = ev[n - 1];
    if (prev.type == e_type) {
      // Alg. 5, rule 1 (2x ENTRY or 2x EXIT): keep the last only...
      prev.cls = e_cls;
      // ...and drop it if it now repeats the class before it (minimality, DESIGN.md "Ray segment lists").
      if (n >= 2u && ev[n - 2].cls == e_cls) {
        --n;
      } else {
        const RayEvent tail = prev;
        const std::uint32_t m = detail::absorb_short_gap(ev, n - 1u, tail, eps);
        if (m != 0xFFFFFFFFu) n = m;
      }
      count_word = n;
      return;
    }
    if (type == EventType::Exit) {  // Alg. 5, rule 2: ENTRY then EXIT, delete both
      count_word = n - 1u;
      return;
    }
    if (n >= 2u && ev[n - 2].cls == e_cls) {  // Alg. 5, rule 3: EXIT then ENTRY back to the same class
      count_word = n - 1u;
      return;
    }
  }
  if (n > 0u && ev[n - 1].cls == e_cls) return;  // no-op event: the class does not change
  // The event is made only now that it is kept (most events fall to a rule above: the CPU builder's
  // hot path).
  const RayEvent e = detail::make_event(t, type, cls);
  const std::uint32_t m = detail::absorb_short_gap(ev, n, e, eps);
  if (m != 0xFFFFFFFFu) {
    count_word = m;
    return;
  }
  if (n >= capacity) {
    // Full: keep what we have and make the open tail conservative (it extends to the volume exit).
    if (n > 0u && ev[n - 1].cls == std::uint8_t(OccupancyClass::Empty)) {
      ev[n - 1].cls = std::uint8_t(OccupancyClass::NonEmpty);
    }
    count_word = n | kListOverflow;
    return;
  }
  ev[n] = e;
  count_word = n + 1u;
}

// Alg. 4 for one box and one ray: FRONT -> ENTRY event with the box's class at the entry t (0 when the
// box holds the ray origin); BACK -> EXIT event with the parent's class at the exit t. Boxes missed
// (t0 >= t1, grazing included) or entirely behind the origin (t1 <= 0) add nothing.
SL_HOST_DEVICE inline void add_box_event(RayEvent* ev, std::uint32_t& count_word, float& t_seen,
                                         std::uint32_t capacity, const Ray& ray, const Box3& box, bool front,
                                         OccupancyClass cls, OccupancyClass parent_cls, float eps) {
  const Interval iv = intersect(ray, box);
  if (iv.empty() || !(iv.t1 > 0.0f)) return;
  if (front) {
    add_event(ev, count_word, t_seen, capacity, iv.t0 > 0.0f ? iv.t0 : 0.0f, EventType::Entry, cls, eps);
  } else {
    add_event(ev, count_word, t_seen, capacity, iv.t1, EventType::Exit, parent_cls, eps);
  }
}

// A fixed-capacity list held by value (CUDA threads, tests).
struct SegmentList {
  RayEvent events[kMaxEvents];
  std::uint32_t count_word = 0;
  float t_seen = kNoEventYet;
  SL_HOST_DEVICE std::uint32_t count() const { return count_word & kListCountMask; }
  SL_HOST_DEVICE bool overflowed() const { return (count_word & kListOverflow) != 0u; }
  SL_HOST_DEVICE void add(float t, EventType type, OccupancyClass cls, float eps = 0.0f) {
    add_event(events, count_word, t_seen, kMaxEvents, t, type, cls, eps);
  }
  SL_HOST_DEVICE void add_box(const Ray& ray, const Box3& box, bool front, OccupancyClass cls,
                              OccupancyClass parent_cls, float eps = 0.0f) {
    add_box_event(events, count_word, t_seen, kMaxEvents, ray, box, front, cls, parent_cls, eps);
  }
};

// A segment of a list, as the caster walks it (Alg. 6).
struct RaySegment {
  float t0 = 0.0f;
  float t1 = 0.0f;
  OccupancyClass cls = OccupancyClass::Invalid;
};

// Number of segments of a list of n events: n - 1 when it ends with INVALID; n when it is open
// (overflowed), its last segment then ending at the volume exit.
SL_HOST_DEVICE inline std::uint32_t segment_count(const RayEvent* ev, std::uint32_t n) {
  if (n == 0u) return 0u;
  return ev[n - 1].cls == std::uint8_t(OccupancyClass::Invalid) ? n - 1u : n;
}
SL_HOST_DEVICE inline RaySegment list_segment(const RayEvent* ev, std::uint32_t n, std::uint32_t k, float t_exit) {
  RaySegment s;
  s.t0 = ev[k].t;
  s.t1 = k + 1u < n ? ev[k + 1].t : t_exit;
  s.cls = OccupancyClass(ev[k].cls);
  return s;
}

// Plain view of all pixels' lists, stored compactly (memory proportional to the events, not to a
// per-pixel capacity): pixel i's count word is counts[i] (low 31 bits: events; top bit: overflow,
// which only a fixed-capacity builder — the GL one — sets), its events are events[offsets[i] ...].
// `event_count` events in all. Pointer-free but for the three arrays, copied to a device as they are
// (cuda/cast_kernels.cuh uploads the arrays and repoints them).
struct SegmentListView {
  const RayEvent* events = nullptr;
  const std::uint32_t* offsets = nullptr;
  const std::uint32_t* counts = nullptr;
  std::uint64_t event_count = 0;
  int width = 0;
  int height = 0;

  SL_HOST_DEVICE std::uint32_t count(std::size_t pixel) const { return counts[pixel] & kListCountMask; }
  SL_HOST_DEVICE bool overflowed(std::size_t pixel) const { return (counts[pixel] & kListOverflow) != 0u; }
  SL_HOST_DEVICE const RayEvent* list(std::size_t pixel) const { return events + offsets[pixel]; }
};
static_assert(sizeof(SegmentListView) == 40, "SegmentListView is copied to the device as it is");

// Host storage of compact lists: one event array shared by all pixels (in any order of the pixels:
// the builders fill it tile by tile) and per pixel an offset and a count word. The arrays only grow:
// a renderer that keeps its buffer allocates nothing per frame once it has seen its largest frame.
struct SegmentListBuffer {
  int width = 0;
  int height = 0;
  std::vector<RayEvent> events;  // [0, event_count) hold the lists; the rest is room to grow into
  std::size_t event_count = 0;
  std::vector<std::uint32_t> offsets;
  std::vector<std::uint32_t> counts;

  // Sizes the per-pixel arrays for w x h pixels, all lists empty. Keeps the storage.
  void reset(int w, int h) {
    SL_CHECK(w >= 0 && h >= 0);
    width = w;
    height = h;
    event_count = 0;
    offsets.assign(std::size_t(w) * std::size_t(h), 0u);
    counts.assign(std::size_t(w) * std::size_t(h), 0u);
  }
  // Sizes the per-pixel arrays for w x h pixels, their contents left as they are: for a builder that
  // writes every pixel's offset and count word itself (no pass to empty them first).
  void reshape(int w, int h) {
    SL_CHECK(w >= 0 && h >= 0);
    width = w;
    height = h;
    event_count = 0;
    offsets.resize(std::size_t(w) * std::size_t(h));
    counts.resize(std::size_t(w) * std::size_t(h));
  }
  // A copy of `v`'s lists (as a device receives them).
  void assign(const SegmentListView& v) {
    const std::size_t pixels = std::size_t(v.width) * std::size_t(v.height);
    width = v.width;
    height = v.height;
    event_count = std::size_t(v.event_count);
    events.assign(v.events, v.events + v.event_count);
    offsets.assign(v.offsets, v.offsets + pixels);
    counts.assign(v.counts, v.counts + pixels);
  }
  std::size_t pixel(int x, int y) const { return std::size_t(y) * std::size_t(width) + std::size_t(x); }
  const RayEvent* list(std::size_t i) const { return events.data() + offsets[i]; }
  std::uint32_t count(std::size_t i) const { return counts[i] & kListCountMask; }
  bool overflowed(std::size_t i) const { return (counts[i] & kListOverflow) != 0u; }
  // Bytes held for the lists: the event array as allocated, and the offsets and count words.
  std::size_t storage_bytes() const {
    return events.capacity() * sizeof(RayEvent) + (offsets.size() + counts.size()) * sizeof(std::uint32_t);
  }
  SegmentListView view() const {
    return SegmentListView{events.data(), offsets.data(), counts.data(), event_count, width, height};
  }
};

}  // namespace sl
