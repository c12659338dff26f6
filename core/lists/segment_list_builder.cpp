// The CPU list builders (core/lists/segment_list_builder.h): the frame's side — entries, screen rectangles,
// tiles and their entries — of the tile builder, whose rasterizer is core/lists/list_tile_raster.h; the
// reference builder, the bbox lists, and the GL lists' compaction.
#include "core/lists/segment_list_builder.h"

#include "core/lists/list_arena.h"
#include "core/lists/list_tile_raster.h"
#include "core/util/parallel.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace sl {

using detail::count_list;
using detail::EventArena;
using detail::ListBlock;
using detail::ListEntry;
using detail::ListTileJob;
using detail::sum_stats;

SegmentListStats segment_list_stats(const SegmentListBuffer& lists) {
  const std::size_t n = lists.counts.size();
  return parallel_reduce(
      std::size_t(0), n, std::size_t(1), SegmentListStats{},
      [&](std::size_t lo, std::size_t hi, SegmentListStats s) {
        for (std::size_t i = lo; i != hi; ++i) count_list(s, lists.list(i), lists.counts[i]);
        return s;
      },
      sum_stats);
}

namespace {

constexpr int T = detail::kListTile;

// Runs fn(tile_rect, entries, stats) for every screen tile, in parallel over rows of tiles: each row
// first bins, in the given order, the items whose rectangle overlaps it (a tile may have none).
// `rect_of(i)` is item i's rectangle. Returns the stats fn added up, with box_tile_pairs.
template <class RectOf, class Fn>
SegmentListStats for_each_tile(const RayGenerator& gen, std::size_t items, RectOf&& rect_of, Fn&& fn) {
  const int tiles_x = (gen.width + T - 1) / T;
  const int tiles_y = (gen.height + T - 1) / T;
  // The items of each row of tiles, in item order, made in one pass over the items (count, prefix
  // sum, fill) instead of one pass per row.
  std::vector<std::uint32_t> row_start(std::size_t(tiles_y) + 1, 0u), row_items;
  for (std::size_t i = 0; i < items; ++i) {
    const ScreenRect& r = rect_of(i);
    if (r.empty()) continue;
    for (int ty = r.y0 / T; ty <= r.y1 / T; ++ty) ++row_start[std::size_t(ty) + 1];
  }
  for (int ty = 0; ty < tiles_y; ++ty) row_start[std::size_t(ty) + 1] += row_start[std::size_t(ty)];
  row_items.resize(row_start.back());
  std::vector<std::uint32_t> at(row_start.begin(), row_start.end() - 1);
  for (std::size_t i = 0; i < items; ++i) {
    const ScreenRect& r = rect_of(i);
    if (r.empty()) continue;
    for (int ty = r.y0 / T; ty <= r.y1 / T; ++ty) row_items[at[std::size_t(ty)]++] = std::uint32_t(i);
  }
  return parallel_reduce(
      0, tiles_y, 1, SegmentListStats{},
      [&](int row0, int row1, SegmentListStats st) {
        thread_local std::vector<std::vector<std::uint32_t>> bins;  // kept: no allocation per frame
        if (bins.size() < std::size_t(tiles_x)) bins.resize(std::size_t(tiles_x));
        for (int ty = row0; ty != row1; ++ty) {
          for (int tx = 0; tx < tiles_x; ++tx) bins[tx].clear();
          const int y0 = ty * T, y1 = std::min(y0 + T, gen.height) - 1;
          for (std::uint32_t j = row_start[std::size_t(ty)]; j != row_start[std::size_t(ty) + 1]; ++j) {
            const std::uint32_t i = row_items[j];
            const ScreenRect& r = rect_of(i);
            for (int tx = r.x0 / T; tx <= r.x1 / T; ++tx) bins[tx].push_back(i);
          }
          for (int tx = 0; tx < tiles_x; ++tx) {
            const ScreenRect tile{tx * T, y0, std::min(tx * T + T, gen.width) - 1, y1};
            st.box_tile_pairs += bins[tx].size();
            fn(tile, bins[tx], st);
          }
        }
        return st;
      },
      sum_stats);
}

std::vector<ScreenRect> box_rects(std::span<const OccupancyBox> boxes, const RayGenerator& gen) {
  std::vector<ScreenRect> rects(boxes.size());
  parallel_for(std::size_t(0), boxes.size(), [&](std::size_t i) { rects[i] = conservative_screen_rect(boxes[i].box, gen); });
  return rects;
}

// The frame's entry records, in `rec` (kept by the caller between frames: no allocation, no zero
// fill per frame once it has seen its largest order). One parallel pass makes them, a FRONT entry's
// with its box's screen rectangle; a BACK entry then takes its FRONT entry's rectangle. Checks what
// the tile builder relies on: every BACK entry closes the box opened last. `depth`: the deepest
// nesting level + 1.
void entry_records(const OccupancyGeometry& geometry, std::span<const VisibilityEntry> order, const RayGenerator& gen,
                   std::vector<ListEntry>& rec, std::uint32_t& depth) {
  // Kept per calling thread; the parallel loop's workers see them through these references (a
  // thread_local named in a lambda would be the worker's own).
  thread_local std::vector<std::uint32_t> level_kept, opener_kept, open_kept;
  std::vector<std::uint32_t>& level = level_kept;
  std::vector<std::uint32_t>& opener = opener_kept;  // a BACK entry's FRONT entry
  std::vector<std::uint32_t>& open = open_kept;
  level.resize(order.size());
  opener.resize(order.size());
  open.clear();
  depth = 0;
  for (std::size_t i = 0; i < order.size(); ++i) {
    if (order[i].face == Face::Front) {
      level[i] = std::uint32_t(open.size());
      open.push_back(std::uint32_t(i));
      depth = std::max(depth, std::uint32_t(open.size()));
    } else {
      SL_CHECK(!open.empty() && order[open.back()].box == order[i].box);
      opener[i] = open.back();
      open.pop_back();
      level[i] = std::uint32_t(open.size());
    }
  }
  SL_CHECK(open.empty());
  rec.resize(order.size());
  parallel_for(std::size_t(0), order.size(), [&](std::size_t lo, std::size_t hi) {
    for (std::size_t e = lo; e != hi; ++e) {
      const VisibilityEntry& v = order[e];
      const OccupancyBox& b = geometry.boxes[v.box];
      const bool front = v.face == Face::Front;
      const bool leaf = front && e + 1 < order.size() && order[e + 1].box == v.box;
      rec[e] = ListEntry{b.box, front ? conservative_screen_rect(b.box, gen) : ScreenRect{}, level[e], b.cls,
                        b.parent_cls, front, leaf};
    }
  });
  for (std::size_t e = 0; e < order.size(); ++e) {
    if (!rec[e].front) rec[e].rect = rec[opener[e]].rect;
  }
}

}  // namespace

SegmentListStats build_segment_lists(const OccupancyGeometry& geometry, std::span<const VisibilityEntry> order,
                                     const RayGenerator& gen, SegmentListBuffer& out, float eps, ListBuildPath path) {
  out.reshape(gen.width, gen.height);  // build_tile writes every pixel
  std::uint32_t depth = 0;
  thread_local std::vector<ListEntry> entries_kept;  // per calling thread, kept between frames
  std::vector<ListEntry>& entries = entries_kept;    // (the workers see it through this reference)
  entry_records(geometry, order, gen, entries, depth);
  EventArena arena(out);
  const ListTileJob job{entries, gen, depth, eps, arena, out};
  const SegmentListStats st = for_each_tile(
      gen, entries.size(), [&](std::size_t i) -> const ScreenRect& { return entries[i].rect; },
      [&](const ScreenRect& tile, const std::vector<std::uint32_t>& items, SegmentListStats& s) {
        detail::build_list_tile(job, tile, items, s, path);
      });
  arena.finish();
  return st;
}

SegmentListStats build_segment_lists_reference(const OccupancyGeometry& geometry,
                                               std::span<const VisibilityEntry> order, const RayGenerator& gen,
                                               SegmentListBuffer& out, float eps, std::uint32_t capacity) {
  out.reset(gen.width, gen.height);
  EventArena arena(out);
  const SegmentListStats st = parallel_reduce(
      0, gen.height, 1, SegmentListStats{},
      [&](int row0, int row1, SegmentListStats s) {
        ListBlock block;
        std::vector<RayEvent> list(capacity > 0u ? capacity : kMaxEvents);
        for (int y = row0; y != row1; ++y) {
          block.clear();
          for (int x = 0; x < gen.width; ++x) {
            const Ray ray = gen.ray(x, y);
            std::uint32_t count = 0;
            for (;;) {
              count = 0;
              float t_seen = kNoEventYet;
              for (const VisibilityEntry& v : order) {
                const OccupancyBox& b = geometry.boxes[v.box];
                add_box_event(list.data(), count, t_seen, std::uint32_t(list.size()), ray, b.box,
                              v.face == Face::Front, b.cls, b.parent_cls, eps);
              }
              if (capacity > 0u || !(count & kListOverflow)) break;
              list.resize(2 * list.size());  // unbounded: the pixel again with room for its list
            }
            block.add(out.pixel(x, y), list.data(), count);
          }
          block.commit(arena, out, s);
        }
        return s;
      },
      sum_stats);
  arena.finish();
  return st;
}

SegmentListStats build_bbox_lists(std::span<const OccupancyBox> all_boxes, const RayGenerator& gen,
                                  SegmentListBuffer& out) {
  out.reset(gen.width, gen.height);
  std::vector<OccupancyBox> boxes;
  for (const OccupancyBox& b : all_boxes) {
    if (b.cls != OccupancyClass::Empty) boxes.push_back(b);
  }
  const std::vector<ScreenRect> rects = box_rects(boxes, gen);
  EventArena arena(out);
  const SegmentListStats st = for_each_tile(
      gen, boxes.size(), [&](std::size_t i) -> const ScreenRect& { return rects[i]; },
      [&](const ScreenRect& tile, const std::vector<std::uint32_t>& items, SegmentListStats& s) {
        if (items.empty()) return;  // the buffer's lists start empty
        thread_local ListBlock block;
        block.clear();
        for (int y = tile.y0; y <= tile.y1; ++y) {
          for (int x = tile.x0; x <= tile.x1; ++x) {
            const Ray ray = gen.ray(x, y);
            float first = HUGE_VALF, last = -HUGE_VALF;
            bool unknown = false;
            for (std::uint32_t i : items) {
              const ScreenRect& r = rects[i];
              if (x < r.x0 || x > r.x1 || y < r.y0 || y > r.y1) continue;
              const Interval iv = intersect(ray, boxes[i].box);
              if (iv.empty() || !(iv.t1 > 0.0f)) continue;
              first = std::min(first, std::max(iv.t0, 0.0f));
              last = std::max(last, iv.t1);
              unknown = unknown || boxes[i].cls == OccupancyClass::Unknown;
            }
            if (!(last > first)) continue;
            const OccupancyClass cls = unknown ? OccupancyClass::Unknown : OccupancyClass::NonEmpty;
            const RayEvent ev[2] = {detail::make_event(first, EventType::Entry, cls),
                                    detail::make_event(last, EventType::Exit, OccupancyClass::Invalid)};
            block.add(out.pixel(x, y), ev, 2u);
          }
        }
        block.commit(arena, out, s);
      });
  arena.finish();
  return st;
}

SegmentListStats compact_fixed_lists(const RayEvent* events, const std::uint32_t* counts, std::uint32_t capacity,
                                     int width, int height, SegmentListBuffer& out) {
  out.reset(width, height);
  EventArena arena(out);
  const SegmentListStats st = parallel_reduce(
      0, height, 1, SegmentListStats{},
      [&](int row0, int row1, SegmentListStats s) {
        for (int y = row0; y != row1; ++y) {  // a row's lists back to back
          const std::size_t p0 = out.pixel(0, y), p1 = p0 + std::size_t(width);
          std::size_t total = 0;
          for (std::size_t p = p0; p < p1; ++p) total += counts[p] & kListCountMask;
          std::uint32_t at = 0;
          RayEvent* const dst = arena.reserve(total, at);
          std::uint32_t run = 0;
          for (std::size_t p = p0; p < p1; ++p) {
            const std::uint32_t c = counts[p] & kListCountMask;
            std::copy_n(events + p * capacity, c, dst + run);
            out.offsets[p] = at + run;
            out.counts[p] = counts[p];
            count_list(s, dst + run, counts[p]);
            run += c;
          }
        }
        return s;
      },
      sum_stats);
  arena.finish();
  return st;
}

}  // namespace sl
