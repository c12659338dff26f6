// The exact CPU builder of ray segment lists (paper §7.3; DESIGN.md §7): a software rasterizer over
// screen tiles. Each tile takes, in visibility order, the entries whose box's conservative screen
// rectangle overlaps it, and for every covered pixel intersects the pixel's ray with the box (the slab
// test decides hits, exactly as the GL fragment shader does) and adds the event (Alg. 4-5).
// Deterministic for any thread count: a pixel's list depends only on the order of the entries.
#pragma once

#include <cstdint>
#include <span>

#include "core/camera.h"
#include "core/occupancy_geometry.h"
#include "core/ray.h"
#include "core/segment_list.h"
#include "core/visibility_order.h"

namespace sl {

// Inclusive pixel rectangle; empty when x0 > x1 or y0 > y1.
struct ScreenRect {
  int x0 = 0, y0 = 0, x1 = -1, y1 = -1;
  bool empty() const { return x0 > x1 || y0 > y1; }
};

// Every pixel whose ray can hit `box` at some t > 0 lies in this rectangle: the projected corners'
// bounds grown by 2 pixels; the full screen when the box holds the eye or straddles the eye plane
// (perspective); empty when the box lies wholly behind the eye plane. The GL builder uses the same
// rectangle for its primitive.
ScreenRect conservative_screen_rect(const Box3& box, const RayGenerator& gen);

struct SegmentListStats {
  std::uint64_t lists = 0;           // pixels with a non-empty list (rays that met the volume)
  std::uint64_t events = 0;          // events in all lists
  std::uint64_t segments = 0;        // segments in all lists (depth complexity, paper Fig. 7)
  std::uint32_t max_events = 0;      // longest list
  std::uint64_t overflows = 0;       // lists that reached their capacity (made conservative)
  std::uint64_t box_tile_pairs = 0;  // visibility entries processed per tile (builder work)
};

// Counts of a built buffer.
SegmentListStats segment_list_stats(const SegmentListBuffer& lists);

// Tile builder. `out` is reset to gen's size, keeping its capacity (kMaxEvents by default).
// eps > 0 enables the conservative short-gap rule (typically one sample step).
SegmentListStats build_segment_lists(const OccupancyGeometry& geometry, std::span<const VisibilityEntry> order,
                                     const RayGenerator& gen, SegmentListBuffer& out, float eps = 0.0f);

// Brute force: every pixel walks every entry (the reference the tile builder must equal).
SegmentListStats build_segment_lists_reference(const OccupancyGeometry& geometry,
                                               std::span<const VisibilityEntry> order, const RayGenerator& gen,
                                               SegmentListBuffer& out, float eps = 0.0f);

// Bounding-geometry baseline: per pixel one segment from the first entry to the last exit over the
// boxes whose class is not EMPTY (UNKNOWN when any UNKNOWN box is hit, else NON_EMPTY), then INVALID.
// Pass geometry.boxes, or leaf_boxes(tree) for "first entry / last exit of non-empty bricks".
// `out` gets capacity 2.
SegmentListStats build_bbox_lists(std::span<const OccupancyBox> boxes, const RayGenerator& gen,
                                  SegmentListBuffer& out);

}  // namespace sl
