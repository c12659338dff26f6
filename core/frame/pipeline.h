// The frame pipeline every renderer and backend shares (STYLE.md #12): frame setup; the SparseLeap
// skipping structures of an occupancy tree — occupancy geometry (paper Alg. 2) → visibility order
// (Alg. 3) → segment lists (Alg. 4–5), or the bounding-geometry lists — each stage timed into Stats,
// the lists reused while the view is unchanged (DESIGN.md "Ray segment lists"); and the overlays and total time that
// end the frame. The in-core renderer gives it the tree it builds from block classes (and keeps the
// octree baseline on top); the out-of-core renderer the tree it grows lazily. The cast parameters come
// from make_cast_params (core/frame/frame.h), the cast from the backend.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <vector>

#include "core/scene/camera.h"
#include "core/frame/frame.h"
#include "core/occupancy/occupancy_geometry.h"
#include "core/lists/segment_list.h"
#include "core/lists/segment_list_builder.h"
#include "core/lists/visibility_order.h"

namespace sl {

// Builds SparseLeap segment lists with build_segment_lists's signature into `out` (sized to gen, its
// storage reused), e.g. GlSegmentListBuilder for `--lists gl`; lists equal to the CPU builder's give
// the same image (DESIGN.md "Ray segment lists", tests/gl/gl_lists_renderer_test.cpp).
using ListBuilder = std::function<SegmentListStats(const OccupancyGeometry&, std::span<const VisibilityEntry>,
                                                   const RayGenerator&, SegmentListBuffer& out, float eps)>;

// A frame of the settings' size (image with its channels), its stats header filled.
Frame begin_frame(const RenderSettings& settings);

class FramePipeline {
 public:
  // The occupancy geometry of `tree`, rebuilt only when the tree changed (its revision); the stage's
  // time and box count go into `st`.
  const OccupancyGeometry& geometry(const OccupancyTree& tree, Stats& st);
  // The per-pixel lists of `method` (SparseLeap: visibility order and segment lists over geometry(),
  // which must be current; BBox: first entry / last exit of the non-empty leaves). Reused while the
  // view, the tree, the method and the short-gap threshold `eps` are unchanged (a step, lighting or
  // opacity-scale change keeps them); otherwise rebuilt, timed into `st`. Fills st.events,
  // st.list_overflows, st.list_bytes and the builder's work counters either way.
  // `tight` (SparseLeap, optional): geometry() of the same tree revision with other boxes and extents
  // (flatten_sparse_subtrees, tighten_leaf_boxes), used instead of it; the lists are reused
  // only while the boxes are the same.
  SegmentListView lists(const OccupancyTree& tree, SkipMethod method, const RayGenerator& gen, float eps,
                        Stats& st, const OccupancyGeometry* tight = nullptr);
  // Ends the frame: the settings' overlays — the depth-complexity view; the occupancy boxes, when the
  // geometry was built from `tree` as it is now (null: no tree) — and the total time since `total`.
  void finish_frame(Frame& frame, const RenderSettings& settings, const OccupancyTree* tree,
                    const RayGenerator& gen, const Timer& total) const;

  // Builds the SparseLeap lists instead of build_segment_lists (empty: the CPU builder).
  void set_list_builder(ListBuilder builder);
  // Forces the next lists() to rebuild even if nothing changed (benchmarks measure rasterization
  // frames honestly this way).
  void invalidate_lists() { lists_valid_ = false; }

 private:
  std::optional<OccupancyGeometry> geometry_;
  std::vector<OccupancyBox> nonempty_leaves_;  // bbox baseline, of tree revision leaves_revision_
  std::uint64_t leaves_revision_ = 0;
  SegmentListBuffer lists_;  // kept between frames: its storage only grows (no allocation per frame)
  // Key of the lists in `lists_`: view, tree revision, method and gap threshold they were built for.
  bool lists_valid_ = false;
  RayGenerator lists_gen_;
  std::uint64_t lists_revision_ = 0;
  SkipMethod lists_method_ = SkipMethod::None;
  float lists_eps_ = 0.0f;
  std::vector<OccupancyBox> lists_boxes_;  // SparseLeap: the boxes the lists were built from
  SegmentListStats list_stats_;
  ListBuilder list_builder_;
};

}  // namespace sl
