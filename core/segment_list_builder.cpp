#include "core/segment_list_builder.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <vector>

#include <glm/gtc/type_precision.hpp>

#include "core/parallel.h"

namespace sl {

ScreenRect conservative_screen_rect(const Box3& box, const RayGenerator& gen) {
  const glm::dvec3 eye(gen.eye), fwd(gen.forward), right(gen.right), up(gen.up);
  double zmin = HUGE_VAL, zmax = -HUGE_VAL, xmin = HUGE_VAL, xmax = -HUGE_VAL, ymin = HUGE_VAL, ymax = -HUGE_VAL;
  double dmax = 0.0;
  glm::dvec3 v[8];
  for (int k = 0; k < 8; ++k) {
    const glm::dvec3 c((k & 1) ? box.hi.x : box.lo.x, (k & 2) ? box.hi.y : box.lo.y, (k & 4) ? box.hi.z : box.lo.z);
    v[k] = c - eye;
    const double z = glm::dot(v[k], fwd);
    zmin = std::min(zmin, z);
    zmax = std::max(zmax, z);
    dmax = std::max(dmax, glm::length(v[k]));
  }
  // Rays move forward (perspective: every direction has a positive forward component; orthographic:
  // origins on the eye plane), so a box wholly behind the eye plane is met only at t <= 0. The
  // tolerance keeps boxes touching the plane, where float slab tests may still report t1 > 0.
  const double tol = 1e-5 * dmax + 1e-30;
  if (zmax < -tol) return ScreenRect{};
  const ScreenRect full{0, 0, gen.width - 1, gen.height - 1};
  if (!gen.orthographic && zmin <= tol) return full;  // holds the eye or straddles the eye plane
  for (int k = 0; k < 8; ++k) {
    double x = glm::dot(v[k], right), y = glm::dot(v[k], up);
    if (!gen.orthographic) {
      const double z = glm::dot(v[k], fwd);
      x /= z;
      y /= z;
    }
    xmin = std::min(xmin, x);
    xmax = std::max(xmax, x);
    ymin = std::min(ymin, y);
    ymax = std::max(ymax, y);
  }
  // Inverse of RayGenerator::ray: screen coordinate -> continuous pixel index of the pixel centre.
  const double half_h = gen.half_h, half_w = double(gen.half_h) * double(gen.aspect);
  auto px = [&](double sx) { return (sx / half_w + 1.0) * 0.5 * gen.width - 0.5; };
  auto py = [&](double sy) { return (1.0 - sy / half_h) * 0.5 * gen.height - 0.5; };
  constexpr double kMargin = 2.0;  // pixels: float ray generation and slab-test rounding
  const double fx0 = std::floor(px(xmin) - kMargin), fx1 = std::ceil(px(xmax) + kMargin);
  const double fy0 = std::floor(py(ymax) - kMargin), fy1 = std::ceil(py(ymin) + kMargin);
  if (fx1 < 0.0 || fy1 < 0.0 || fx0 > gen.width - 1 || fy0 > gen.height - 1) return ScreenRect{};
  ScreenRect r;
  r.x0 = int(std::max(fx0, 0.0));
  r.y0 = int(std::max(fy0, 0.0));
  r.x1 = int(std::min(fx1, double(gen.width - 1)));
  r.y1 = int(std::min(fy1, double(gen.height - 1)));
  return r;
}

SegmentListStats segment_list_stats(const SegmentListBuffer& lists) {
  const std::size_t n = lists.counts.size();
  return parallel_reduce(
      std::size_t(0), n, std::size_t(1), SegmentListStats{},
      [&](std::size_t lo, std::size_t hi, SegmentListStats s) {
        for (std::size_t i = lo; i != hi; ++i) {
          const std::uint32_t c = lists.count(i);
          if (c == 0u) continue;
          ++s.lists;
          s.events += c;
          s.segments += segment_count(lists.list(i), c);
          s.max_events = std::max(s.max_events, c);
          s.overflows += lists.overflowed(i) ? 1u : 0u;
        }
        return s;
      },
      [](SegmentListStats a, const SegmentListStats& b) {
        a.lists += b.lists;
        a.events += b.events;
        a.segments += b.segments;
        a.max_events = std::max(a.max_events, b.max_events);
        a.overflows += b.overflows;
        a.box_tile_pairs += b.box_tile_pairs;
        return a;
      });
}

namespace {

// Runs fn(tile_rect, entries) for every screen tile, in parallel over rows of tiles: each row first
// bins, in the given order, the items whose rectangle overlaps it. `rect_of(i)` is item i's rectangle.
template <class RectOf, class Fn>
std::uint64_t for_each_tile(const RayGenerator& gen, std::size_t items, RectOf&& rect_of, Fn&& fn) {
  constexpr int T = kTileSize;
  const int tiles_x = (gen.width + T - 1) / T;
  const int tiles_y = (gen.height + T - 1) / T;
  std::atomic<std::uint64_t> pairs{0};
  parallel_for(0, tiles_y, [&](int row0, int row1) {
    std::vector<std::vector<std::uint32_t>> bins(tiles_x);  // once per chunk of rows
    for (int ty = row0; ty != row1; ++ty) {
      for (auto& b : bins) b.clear();
      const int y0 = ty * T, y1 = std::min(y0 + T, gen.height) - 1;
      for (std::size_t i = 0; i < items; ++i) {
        const ScreenRect& r = rect_of(i);
        if (r.empty() || r.y1 < y0 || r.y0 > y1) continue;
        for (int tx = r.x0 / T; tx <= r.x1 / T; ++tx) bins[tx].push_back(std::uint32_t(i));
      }
      std::uint64_t p = 0;
      for (int tx = 0; tx < tiles_x; ++tx) {
        const ScreenRect tile{tx * T, y0, std::min(tx * T + T, gen.width) - 1, y1};
        p += bins[tx].size();
        fn(tile, bins[tx]);
      }
      pairs += p;
    }
  });
  return pairs.load();
}

std::vector<ScreenRect> box_rects(std::span<const OccupancyBox> boxes, const RayGenerator& gen) {
  std::vector<ScreenRect> rects(boxes.size());
  parallel_for(std::size_t(0), boxes.size(),
               [&](std::size_t i) { rects[i] = conservative_screen_rect(boxes[i].box, gen); });
  return rects;
}

}  // namespace

SegmentListStats build_segment_lists(const OccupancyGeometry& geometry, std::span<const VisibilityEntry> order,
                                     const RayGenerator& gen, SegmentListBuffer& out, float eps) {
  out.reset(gen.width, gen.height, out.capacity);
  const std::vector<ScreenRect> rects = box_rects(geometry.boxes, gen);
  const std::uint32_t cap = out.capacity;
  const std::uint64_t pairs = for_each_tile(
      gen, order.size(), [&](std::size_t i) -> const ScreenRect& { return rects[order[i].box]; },
      [&](const ScreenRect& tile, const std::vector<std::uint32_t>& entries) {
        if (entries.empty()) return;
        Ray rays[kTileSize * kTileSize];
        float t_seen[kTileSize * kTileSize];
        const int tw = tile.x1 - tile.x0 + 1;
        for (int y = tile.y0; y <= tile.y1; ++y) {
          for (int x = tile.x0; x <= tile.x1; ++x) {
            rays[(y - tile.y0) * tw + (x - tile.x0)] = gen.ray(x, y);
            t_seen[(y - tile.y0) * tw + (x - tile.x0)] = kNoEventYet;
          }
        }
        for (std::uint32_t e : entries) {
          const VisibilityEntry& v = order[e];
          const OccupancyBox& b = geometry.boxes[v.box];
          const ScreenRect& r = rects[v.box];
          const int x0 = std::max(r.x0, tile.x0), x1 = std::min(r.x1, tile.x1);
          const int y0 = std::max(r.y0, tile.y0), y1 = std::min(r.y1, tile.y1);
          for (int y = y0; y <= y1; ++y) {
            for (int x = x0; x <= x1; ++x) {
              const std::size_t p = out.pixel(x, y);
              const int k = (y - tile.y0) * tw + (x - tile.x0);
              add_box_event(out.list(p), out.counts[p], t_seen[k], cap, rays[k], b.box, v.face == Face::Front, b.cls,
                            b.parent_cls, eps);
            }
          }
        }
      });
  SegmentListStats s = segment_list_stats(out);
  s.box_tile_pairs = pairs;
  return s;
}

SegmentListStats build_segment_lists_reference(const OccupancyGeometry& geometry,
                                               std::span<const VisibilityEntry> order, const RayGenerator& gen,
                                               SegmentListBuffer& out, float eps) {
  out.reset(gen.width, gen.height, out.capacity);
  parallel_for(0, gen.height, [&](int y) {
    for (int x = 0; x < gen.width; ++x) {
      const Ray ray = gen.ray(x, y);
      const std::size_t p = out.pixel(x, y);
      float t_seen = kNoEventYet;
      for (const VisibilityEntry& v : order) {
        const OccupancyBox& b = geometry.boxes[v.box];
        add_box_event(out.list(p), out.counts[p], t_seen, out.capacity, ray, b.box, v.face == Face::Front, b.cls,
                      b.parent_cls, eps);
      }
    }
  });
  return segment_list_stats(out);
}

SegmentListStats build_bbox_lists(std::span<const OccupancyBox> all_boxes, const RayGenerator& gen,
                                  SegmentListBuffer& out) {
  out.reset(gen.width, gen.height, 2u);
  std::vector<OccupancyBox> boxes;
  for (const OccupancyBox& b : all_boxes) {
    if (b.cls != OccupancyClass::Empty) boxes.push_back(b);
  }
  const std::vector<ScreenRect> rects = box_rects(boxes, gen);
  const std::uint64_t pairs = for_each_tile(
      gen, boxes.size(), [&](std::size_t i) -> const ScreenRect& { return rects[i]; },
      [&](const ScreenRect& tile, const std::vector<std::uint32_t>& items) {
        if (items.empty()) return;
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
            const std::size_t p = out.pixel(x, y);
            RayEvent* ev = out.list(p);
            ev[0] = detail::make_event(first, EventType::Entry,
                                       unknown ? OccupancyClass::Unknown : OccupancyClass::NonEmpty);
            ev[1] = detail::make_event(last, EventType::Exit, OccupancyClass::Invalid);
            out.counts[p] = 2u;
          }
        }
      });
  SegmentListStats s = segment_list_stats(out);
  s.box_tile_pairs = pairs;
  return s;
}

}  // namespace sl
