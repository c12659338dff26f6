// Where the CPU list builders (core/lists/segment_list_builder.cpp) put their lists: the frame's event
// array, handed out to many threads at once (EventArena), blocks of lists on their way into it
// (ListBlock), and the counts of built lists. Host only; internal to the builders.
#pragma once

#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <atomic>
#include <memory>
#include <vector>

#include "core/lists/segment_list_builder.h"

namespace sl::detail {

inline void add_stats(SegmentListStats& a, const SegmentListStats& b) {
  a.lists += b.lists;
  a.events += b.events;
  a.segments += b.segments;
  a.max_events = std::max(a.max_events, b.max_events);
  a.overflows += b.overflows;
  a.box_tile_pairs += b.box_tile_pairs;
  a.slab_tests += b.slab_tests;
}

inline SegmentListStats sum_stats(SegmentListStats a, const SegmentListStats& b) {
  add_stats(a, b);
  return a;
}

// One list into the counts (an empty list counts for nothing, whatever its flag).
inline void count_list(SegmentListStats& s, const RayEvent* ev, std::uint32_t word) {
  const std::uint32_t c = word & kListCountMask;
  if (c == 0u) return;
  ++s.lists;
  s.events += c;
  s.segments += segment_count(ev, c);
  s.max_events = std::max(s.max_events, c);
  s.overflows += (word & kListOverflow) ? 1u : 0u;
}

// Hands out ranges of out.events to many threads at once: a block of lists reserves its range with
// one atomic add and writes itself there. A range past the end of the array (a frame with more events
// than any before it) goes to the thread's spill chunks instead, appended once finish() has grown the
// array: only such frames allocate. Neither the chunks nor the array's new part are zero-filled
// first (value-initialising RayEvents is a scalar loop over all of them).
// Offsets are 32-bit: an image holds up to 2^32 events (32 GiB).
class EventArena {
 public:
  explicit EventArena(SegmentListBuffer& out) : out_(out) {}

  // Room for n events, to be written before this thread's next reserve(); `at` is their offset.
  RayEvent* reserve(std::size_t n, std::uint32_t& at) {
    const std::size_t first = used_.fetch_add(n, std::memory_order_relaxed);
    at = std::uint32_t(first);
    if (first + n <= out_.events.size()) return out_.events.data() + first;
    // Nothing to write (a row without events): no spilled range, whose `at` would tie with the range
    // that does hold events there and could sort after it in finish().
    if (n == 0) return out_.events.data() + out_.events.size();
    Spill& s = spilled_.local();
    if (s.chunks.empty() || s.used + n > s.chunk_size) {
      s.chunk_size = std::max(n, kChunkEvents);
      s.chunks.push_back(std::make_unique_for_overwrite<RayEvent[]>(s.chunk_size));
      s.used = 0;
    }
    RayEvent* const p = s.chunks.back().get() + s.used;
    s.used += n;
    s.ranges.push_back(Range{first, p, n});
    return p;
  }

  // After every block is written: grows the array (with an eighth to spare, so that the frames of a
  // camera path rarely grow it again) and appends the spilled ranges. A range is spilled when it
  // ends past the array's end, so the spilled ranges, in offset order, tile [their first, total):
  // the array is cut there and they are appended one after the other.
  void finish() {
    const std::size_t total = used_.load();
    SL_CHECK(total <= std::size_t(0xFFFFFFFFu));
    if (total > out_.events.size()) {
      std::vector<Range> ranges;
      for (const Spill& s : spilled_) ranges.insert(ranges.end(), s.ranges.begin(), s.ranges.end());
      std::sort(ranges.begin(), ranges.end(), [](const Range& a, const Range& b) { return a.at < b.at; });
      SL_CHECK(!ranges.empty() && ranges.front().at <= out_.events.size());
      out_.events.resize(ranges.front().at);         // drops nothing written: that part spilled
      out_.events.reserve(total + total / 8);        // exactly: growing by insert may double it
      for (const Range& r : ranges) {
        SL_DCHECK(r.at == out_.events.size());
        out_.events.insert(out_.events.end(), r.from, r.from + r.n);
      }
      SL_CHECK(out_.events.size() == total);
      out_.events.resize(total + total / 8);  // the spare eighth (zeroed; unused until a bigger frame)
    }
    out_.event_count = total;
  }

 private:
  static constexpr std::size_t kChunkEvents = std::size_t(1) << 16;
  struct Range {
    std::size_t at;
    const RayEvent* from;
    std::size_t n;  // offset in the array, where the events wait; events
  };
  struct Spill {
    std::vector<std::unique_ptr<RayEvent[]>> chunks;
    std::size_t used = 0, chunk_size = 0;  // of the last chunk
    std::vector<Range> ranges;
  };
  SegmentListBuffer& out_;
  std::atomic<std::size_t> used_{0};
  tbb::enumerable_thread_specific<Spill> spilled_;  // made per thread only when it spills
};

// One block's lists (a row's, a tile's) back to back, on their way into the buffer.
struct ListBlock {
  std::vector<RayEvent> events;
  std::vector<std::uint32_t> pixel, start, word;

  void clear() {
    events.clear();
    pixel.clear();
    start.clear();
    word.clear();
  }
  void add(std::size_t p, const RayEvent* ev, std::uint32_t count_word) {
    if (count_word == 0u) return;  // the buffer's lists start empty
    pixel.push_back(std::uint32_t(p));
    start.push_back(std::uint32_t(events.size()));
    word.push_back(count_word);
    events.insert(events.end(), ev, ev + (count_word & kListCountMask));
  }
  // Into the buffer through `arena`, counting the lists into `st`.
  void commit(EventArena& arena, SegmentListBuffer& out, SegmentListStats& st) const {
    if (pixel.empty()) return;
    std::uint32_t base = 0;
    std::copy(events.begin(), events.end(), arena.reserve(events.size(), base));
    for (std::size_t i = 0; i < pixel.size(); ++i) {
      out.offsets[pixel[i]] = base + start[i];
      out.counts[pixel[i]] = word[i];
      count_list(st, events.data() + start[i], word[i]);
    }
  }
};

}  // namespace sl::detail
