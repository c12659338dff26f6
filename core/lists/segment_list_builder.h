// The exact CPU builder of ray segment lists (paper §7.3; DESIGN.md "Ray segment lists"): a software rasterizer over
// screen tiles. Each tile takes, in visibility order, the entries whose box's conservative screen
// rectangle overlaps it, and for every covered pixel intersects the pixel's ray with the box (the slab
// test decides hits, exactly as the GL fragment shader does) and adds the event (Alg. 4-5).
//
// Its fast paths, each with a scalar twin it is tested against (STYLE.md #15):
//  - slab tests and lane masks on eight pixels at once (AVX2, chosen at run time) or four (SSE2;
//    ListBuildPath::Scalar is the twin), the slab test lane for lane intersect()'s result (slab4);
//  - a box's BACK entry reuses the exit its FRONT entry found: the visibility order is depth-first
//    (FRONT in pre-order, BACK in post-order), so for one pixel the entries of the boxes covering it
//    nest like parentheses, and one slot per nesting level and pixel holds the exit t of the open box
//    (the twin: the reference builder, which intersects again);
//  - a leaf's two entries (adjacent in the order) are applied in one pass over its pixels;
//  - perspective rays share their origin: the box relative to it once per entry (slab4_shared);
//  - the tile's rays written out per component (tile_rays, gen.ray()'s bits);
//  - a first frame's events are not zero-filled before they are written (EventArena).
// Tighter pixel bounds than the rectangle do not pay here: masking each box's pixels by the exact hit
// set of the box enclosing it saves fewer slab tests than it costs in instructions.
// Lists are built per tile in a scratch of the tile's pixels x a capacity; a tile one of whose lists
// outgrows it is built again with twice the capacity (no overflow, no truncation). The tile's lists
// then go back to back into the buffer's one event array (SegmentListBuffer), which only grows.
// Deterministic for any thread count: a pixel's list depends only on the order of the entries.
#pragma once

#include <cstdint>
#include <span>

#include "core/scene/camera.h"
#include "core/occupancy/occupancy_geometry.h"
#include "core/util/parallel.h"
#include "core/util/ray.h"
#include "core/lists/screen_rays.h"
#include "core/lists/segment_list.h"
#include "core/lists/visibility_order.h"

namespace sl {

// Which code runs the tile builder's lanes (slab tests, lane masks): Fast is the widest the host has —
// eight pixels at once with AVX2 (checked at run time), else four with SSE2, else the scalar code;
// Sse2 is the four-lane code (what Fast runs without AVX2); Scalar is always the scalar twin.
// Renderers use Fast; the tests check that all three give the same lists and, lane for lane,
// intersect()'s hits (STYLE.md #15).
enum class ListBuildPath { Fast, Scalar, Sse2 };

// Whether ListBuildPath::Fast runs eight lanes (AVX2) on this host.
bool list_build_lanes8();

namespace detail {

// Four rays, lanes [i, i + 4) of structure-of-arrays origins o[axis] and slab_reciprocal'd
// directions inv[axis], against `b`. Returns a 4-bit mask: bit k set when lane k's ray hits the box
// at some t > 0 (intersect()'s !empty() && t1 > 0); t0[k], t1[k] are then bit for bit intersect()'s.
template <ListBuildPath kPath>
unsigned slab4(const float* const o[3], const float* const inv[3], std::size_t i, const Box3& b, float* t0,
               float* t1);
extern template unsigned slab4<ListBuildPath::Fast>(const float* const[3], const float* const[3], std::size_t,
                                                    const Box3&, float*, float*);
extern template unsigned slab4<ListBuildPath::Scalar>(const float* const[3], const float* const[3], std::size_t,
                                                      const Box3&, float*, float*);

// slab4 for four rays that share `origin` (perspective), as the tile builder's Fast path runs it: the
// box relative to the origin once, then per lane the same operations, so bit for bit slab4's result.
template <ListBuildPath kPath>
unsigned slab4_shared(const float* const inv[3], std::size_t i, const vec3& origin, const Box3& b, float* t0,
                      float* t1);
extern template unsigned slab4_shared<ListBuildPath::Fast>(const float* const[3], std::size_t, const vec3&,
                                                           const Box3&, float*, float*);
extern template unsigned slab4_shared<ListBuildPath::Scalar>(const float* const[3], std::size_t, const vec3&,
                                                             const Box3&, float*, float*);

// slab4 and slab4_shared eight lanes wide (lanes i .. i + 7), with AVX2: the tile builder's Fast lanes
// where the host has it. Call only where list_build_lanes8().
unsigned slab8(const float* const o[3], const float* const inv[3], std::size_t i, const Box3& b, float* t0, float* t1);
unsigned slab8_shared(const float* const inv[3], std::size_t i, const vec3& origin, const Box3& b, float* t0,
                      float* t1);

}  // namespace detail

struct SegmentListStats {
  std::uint64_t lists = 0;           // pixels with a non-empty list (rays that met the volume)
  std::uint64_t events = 0;          // events in all lists
  std::uint64_t segments = 0;        // segments in all lists (depth complexity, paper Fig. 7)
  std::uint32_t max_events = 0;      // longest list
  std::uint64_t overflows = 0;       // lists that reached a fixed capacity (GL; made conservative)
  std::uint64_t box_tile_pairs = 0;  // visibility entries processed per tile (builder work)
  std::uint64_t slab_tests = 0;      // tile builder: (box, pixel) slab tests (FRONT entries only)
};

// Counts of a built buffer.
SegmentListStats segment_list_stats(const SegmentListBuffer& lists);

// Tile builder into `out` (reset to gen's size; its storage is reused). `order` must be a visibility
// order (build_visibility_order's): depth-first, each box's FRONT and BACK entries nesting (checked).
// eps > 0 enables the conservative short-gap rule (typically one sample step).
SegmentListStats build_segment_lists(const OccupancyGeometry& geometry, std::span<const VisibilityEntry> order,
                                     const RayGenerator& gen, SegmentListBuffer& out, float eps = 0.0f,
                                     ListBuildPath path = ListBuildPath::Fast);

// Brute force: every pixel walks every entry (any order), with a slab test per entry: the oracle the
// tile builder must equal. capacity > 0 bounds each list as a fixed-capacity builder (the GL one)
// does, overflowing lists made conservative (Alg. 5 tail rule of add_event); 0: no bound.
SegmentListStats build_segment_lists_reference(const OccupancyGeometry& geometry,
                                               std::span<const VisibilityEntry> order, const RayGenerator& gen,
                                               SegmentListBuffer& out, float eps = 0.0f, std::uint32_t capacity = 0);

// Bounding-geometry baseline: per pixel one segment from the first entry to the last exit over the
// boxes whose class is not EMPTY (UNKNOWN when any UNKNOWN box is hit, else NON_EMPTY), then INVALID.
// Pass geometry.boxes, or leaf_boxes(tree) for "first entry / last exit of non-empty bricks".
SegmentListStats build_bbox_lists(std::span<const OccupancyBox> boxes, const RayGenerator& gen,
                                  SegmentListBuffer& out);

// Fixed-capacity lists (pixel i's events at events[i * capacity ...], count words with the overflow
// flag: the GL builder's layout) stored compactly into `out`.
SegmentListStats compact_fixed_lists(const RayEvent* events, const std::uint32_t* counts, std::uint32_t capacity,
                                     int width, int height, SegmentListBuffer& out);

}  // namespace sl
