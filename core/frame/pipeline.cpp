#include "core/frame/pipeline.h"

#include <cstring>

#include "core/util/error.h"
#include "core/occupancy/occupancy_tree.h"
#include "core/frame/overlay.h"

namespace sl {

namespace {

// Field by field: the struct has padding bytes, which memcmp would compare too.
bool same_view(const RayGenerator& a, const RayGenerator& b) {
  return a.eye == b.eye && a.forward == b.forward && a.right == b.right && a.up == b.up && a.half_h == b.half_h &&
         a.aspect == b.aspect && a.width == b.width && a.height == b.height && a.orthographic == b.orthographic;
}

}  // namespace

Frame begin_frame(const RenderSettings& s) {
  Frame frame;
  frame.image = Image(s.width, s.height);
  frame.stats.width = s.width;
  frame.stats.height = s.height;
  frame.stats.method = to_string(s.method);
  frame.stats.mode = to_string(s.mode);
  return frame;
}

const OccupancyGeometry& FramePipeline::geometry(const OccupancyTree& tree, Stats& st) {
  Timer t;
  if (!geometry_ || geometry_->tree_revision != tree.revision()) geometry_ = build_occupancy_geometry(tree);
  st.boxes = geometry_->boxes.size();
  st.time_ms.geometry = t.ms();
  return *geometry_;
}

namespace {

bool same_boxes(const std::vector<OccupancyBox>& a, const std::vector<OccupancyBox>& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(OccupancyBox)) == 0);
}

}  // namespace

SegmentListView FramePipeline::lists(const OccupancyTree& tree, SkipMethod method, const RayGenerator& gen,
                                     float eps, Stats& st, const OccupancyGeometry* tight) {
  SL_CHECK(method == SkipMethod::SparseLeap || method == SkipMethod::BBox);
  const OccupancyGeometry* g = tight ? tight : geometry_ ? &*geometry_ : nullptr;
  const bool reuse = lists_valid_ && lists_method_ == method && lists_eps_ == eps &&
                     lists_revision_ == tree.revision() && same_view(lists_gen_, gen) &&
                     (method != SkipMethod::SparseLeap || (g && same_boxes(g->boxes, lists_boxes_)));
  if (!reuse) {
    Timer t;
    if (method == SkipMethod::SparseLeap) {
      SL_CHECK(geometry_ && geometry_->tree_revision == tree.revision());
      SL_CHECK(g->tree_revision == tree.revision());
      const std::vector<VisibilityEntry> order = build_visibility_order(tree, *g, view_point(gen));
      st.time_ms.order = t.ms();
      t = Timer();
      list_stats_ = list_builder_ ? list_builder_(*g, order, gen, lists_, eps) : build_segment_lists(*g, order, gen, lists_, eps);
      lists_boxes_ = g->boxes;
    } else {
      if (leaves_revision_ != tree.revision()) {
        nonempty_leaves_.clear();
        for (const OccupancyBox& b : leaf_boxes(tree)) {
          if (b.cls != OccupancyClass::Empty) nonempty_leaves_.push_back(b);
        }
        leaves_revision_ = tree.revision();
      }
      list_stats_ = build_bbox_lists(nonempty_leaves_, gen, lists_);
    }
    st.time_ms.lists = t.ms();
    lists_valid_ = true;
    lists_method_ = method;
    lists_eps_ = eps;
    lists_revision_ = tree.revision();
    lists_gen_ = gen;
  }
  st.events = list_stats_.events;
  st.list_overflows = list_stats_.overflows;
  st.list_bytes = lists_.storage_bytes();
  st.list_tile_entries = list_stats_.box_tile_pairs;
  st.list_slab_tests = list_stats_.slab_tests;
  return lists_.view();
}

void FramePipeline::finish_frame(Frame& frame, const RenderSettings& s, const OccupancyTree* tree,
                                 const RayGenerator& gen, const Timer& total) const {
  const Stats& st = frame.stats;
  if (s.depth_complexity_view) {
    draw_depth_complexity(frame.image, float(st.depth_complexity_min), float(st.depth_complexity_avg),
                          float(st.depth_complexity_max));
  }
  if (s.boxes_overlay && tree && geometry_ && geometry_->tree_revision == tree->revision()) {
    draw_boxes(frame.image, geometry_->boxes, gen);
  }
  frame.stats.time_ms.total = total.ms();
}

void FramePipeline::set_list_builder(ListBuilder builder) {
  list_builder_ = std::move(builder);
  lists_valid_ = false;
}

}  // namespace sl
