#include "core/in_core_renderer.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <optional>

#include "core/block_metadata.h"
#include "core/cast_frame.h"
#include "core/culling.h"
#include "core/error.h"
#include "core/occupancy_geometry.h"
#include "core/occupancy_tree.h"
#include "core/octree_skip.h"
#include "core/overlay.h"
#include "core/segment_list_builder.h"
#include "core/visibility_order.h"
#include "core/parallel.h"
#include "core/raycast.h"

namespace sl {

// What persists between frames: metadata (computed once per volume and block size, never for a
// transfer-function or label change), the occupancy structures (rebuilt when the block classes
// change), and the segment lists (reused while the view and the geometry are unchanged; DESIGN.md §7).
struct InCoreRenderer::State {
  const Volume* volume = nullptr;
  const Volume* labels = nullptr;
  int block = 0;
  std::optional<BlockMetadataTable> metadata;
  std::vector<OccupancyClass> classes;
  std::optional<OccupancyTree> tree;
  std::optional<OccupancyGeometry> geometry;
  std::optional<SkipOctree> octree;
  std::vector<OccupancyBox> nonempty_leaves;  // bbox baseline
  SegmentListBuffer lists;
  // Key of the lists in `lists`: view, geometry, method and gap threshold they were built for.
  bool lists_valid = false;
  RayGenerator lists_gen;
  std::uint64_t lists_revision = 0;
  SkipMethod lists_method = SkipMethod::None;
  float lists_eps = 0.0f;
  SegmentListStats list_stats;
};

InCoreRenderer::InCoreRenderer() : state_(std::make_unique<State>()) {}
InCoreRenderer::~InCoreRenderer() = default;

namespace {

template <class T>
DenseGrid<T> grid_of(const Volume* v) {
  DenseGrid<T> g;
  if (v && !v->empty()) {
    g.data = v->as<T>();
    g.dims = v->dims();
    g.inv_spacing = 1.0f / v->desc().spacing;
  }
  return g;
}

template <class VT, class LT>
void render_typed(const Scene& scene, const RenderSettings& s, const CastParams& params, const SkipInputs& skip,
                  Frame& frame) {
  RayCaster<DenseSampler<VT, LT>> caster{params, {grid_of<VT>(scene.volume), grid_of<LT>(scene.labels)}};
  const RayGenerator gen = make_ray_generator(scene.camera, s.width, s.height);
  cast_frame(caster, gen, Box3{vec3(0.0f), scene.volume->desc().extent()}, skip, frame);
}

template <class VT>
void render_labels_typed(const Scene& scene, const RenderSettings& s, const CastParams& p, const SkipInputs& k,
                         Frame& f) {
  if (!scene.labels) return render_typed<VT, std::uint8_t>(scene, s, p, k, f);
  switch (scene.labels->type()) {
    case VoxelType::U8: return render_typed<VT, std::uint8_t>(scene, s, p, k, f);
    case VoxelType::U16: return render_typed<VT, std::uint16_t>(scene, s, p, k, f);
    case VoxelType::U32: return render_typed<VT, std::uint32_t>(scene, s, p, k, f);
    case VoxelType::F32: throw InputError("--labels", "label volume must be of an integer type");
  }
}

// Field by field: the struct has padding bytes, which memcmp would compare too.
bool same_view(const RayGenerator& a, const RayGenerator& b) {
  return a.eye == b.eye && a.forward == b.forward && a.right == b.right && a.up == b.up && a.half_h == b.half_h &&
         a.aspect == b.aspect && a.width == b.width && a.height == b.height && a.orthographic == b.orthographic;
}

}  // namespace

// Builds (or reuses) what the method needs: metadata → block classes → occupancy tree → geometry →
// visibility order → segment lists (SparseLeap), the min/max octree (octree) or the first-entry /
// last-exit lists (bbox). Each stage is timed into the frame's stats.
SkipInputs InCoreRenderer::prepare_skipping(const Scene& scene, const RenderSettings& s, const CastParams& p,
                                         Stats& st) {
  SkipInputs in;
  in.method = s.method;
  if (s.method == SkipMethod::None) return in;
  State& S = *state_;
  Timer t;
  if (!S.metadata || S.volume != scene.volume || S.labels != scene.labels || S.block != s.block) {
    S = State{};
    S.volume = scene.volume;
    S.labels = scene.labels;
    S.block = s.block;
    const BlockGrid grid = make_block_grid(scene.volume->dims(), scene.volume->desc().spacing, s.block);
    VolumeView lv;
    if (scene.labels) lv = scene.labels->view();
    S.metadata = compute_all_block_metadata(grid, scene.volume->view(), scene.labels ? &lv : nullptr);
  }
  st.time_ms.metadata = t.ms();
  st.metadata_blocks = S.metadata->blocks.size();

  t = Timer();
  CullParams cull;
  cull.mode = s.mode;
  cull.tf = scene.tf;
  cull.iso = s.iso;
  cull.enabled = (p.label_mask || s.mode == RenderMode::Labels) ? active_labels_ : nullptr;
  std::vector<OccupancyClass> classes = classify_blocks(*S.metadata, cull);
  if (!S.tree || classes != S.classes) {
    // A transfer-function or label change lands here: re-cull from cached metadata (DESIGN.md §5).
    S.classes = std::move(classes);
    if (S.tree) {
      S.tree->reclassify(S.classes);
    } else {
      S.tree = OccupancyTree::from_block_classes(S.metadata->grid, S.classes);
    }
    S.geometry.reset();
    S.octree.reset();
    S.nonempty_leaves.clear();
    S.lists_valid = false;
  }
  st.time_ms.tree = t.ms();
  st.tree_nodes = S.tree->node_count();

  t = Timer();
  if (!S.geometry) S.geometry = build_occupancy_geometry(*S.tree);
  st.boxes = S.geometry->boxes.size();
  st.time_ms.geometry = t.ms();

  const RayGenerator gen = make_ray_generator(scene.camera, s.width, s.height);
  const float eps = s.gap_eps * p.dt;
  switch (s.method) {
    case SkipMethod::Octree: {
      t = Timer();
      if (!S.octree) S.octree.emplace(S.metadata->grid, S.classes);
      st.time_ms.tree += t.ms();
      in.octree = S.octree->view();
      break;
    }
    case SkipMethod::BBox:
    case SkipMethod::SparseLeap: {
      const bool reuse = S.lists_valid && S.lists_method == s.method && S.lists_eps == eps &&
                         S.lists_revision == S.tree->revision() && same_view(S.lists_gen, gen);
      if (!reuse) {
        if (s.method == SkipMethod::SparseLeap) {
          t = Timer();
          const std::vector<VisibilityEntry> order = build_visibility_order(*S.tree, *S.geometry, view_point(gen));
          st.time_ms.order = t.ms();
          t = Timer();
          S.lists.reset(s.width, s.height, kListCapacity);
          S.list_stats = list_builder_ ? list_builder_(*S.geometry, order, gen, S.lists, eps)
                                       : build_segment_lists(*S.geometry, order, gen, S.lists, eps);
          st.time_ms.lists = t.ms();
        } else {
          t = Timer();
          if (S.nonempty_leaves.empty()) {
            for (const OccupancyBox& b : leaf_boxes(*S.tree)) {
              if (b.cls != OccupancyClass::Empty) S.nonempty_leaves.push_back(b);
            }
          }
          S.list_stats = build_bbox_lists(S.nonempty_leaves, gen, S.lists);
          st.time_ms.lists = t.ms();
        }
        S.lists_valid = true;
        S.lists_method = s.method;
        S.lists_eps = eps;
        S.lists_revision = S.tree->revision();
        S.lists_gen = gen;
      }
      st.events = S.list_stats.events;
      st.list_overflows = S.list_stats.overflows;
      in.lists = S.lists.view();
      break;
    }
    case SkipMethod::None: break;
  }
  return in;
}

void InCoreRenderer::invalidate_lists() { state_->lists_valid = false; }

void InCoreRenderer::set_list_builder(ListBuilder builder) {
  list_builder_ = std::move(builder);
  state_->lists_valid = false;
}

void InCoreRenderer::set_caster(Caster caster) { caster_ = std::move(caster); }

const OccupancyGeometry* InCoreRenderer::geometry() const {
  return state_->geometry ? &*state_->geometry : nullptr;
}

Frame InCoreRenderer::render(const Scene& scene, const RenderSettings& s) {
  validate(scene, s);
  Timer total;
  Frame frame;
  frame.image = Image(s.width, s.height);
  frame.stats.width = s.width;
  frame.stats.height = s.height;
  frame.stats.method = to_string(s.method);
  frame.stats.mode = to_string(s.mode);

  LabelSet label_storage;
  const CastParams p = make_cast_params(scene, s, label_storage);
  active_labels_ = scene.enabled ? scene.enabled : (s.mode == RenderMode::Labels ? &label_storage : nullptr);
  const SkipInputs skip = prepare_skipping(scene, s, p, frame.stats);

  if (caster_) {
    caster_(scene, s, p, skip, frame);
  } else {
    switch (scene.volume->type()) {
      case VoxelType::U8: render_labels_typed<std::uint8_t>(scene, s, p, skip, frame); break;
      case VoxelType::U16: render_labels_typed<std::uint16_t>(scene, s, p, skip, frame); break;
      case VoxelType::U32: render_labels_typed<std::uint32_t>(scene, s, p, skip, frame); break;
      case VoxelType::F32: render_labels_typed<float>(scene, s, p, skip, frame); break;
    }
  }
  if (s.depth_complexity_view) {
    draw_depth_complexity(frame.image, float(frame.stats.depth_complexity_min),
                          float(frame.stats.depth_complexity_avg), float(frame.stats.depth_complexity_max));
  }
  if (s.boxes_overlay && state_->geometry) {
    draw_boxes(frame.image, state_->geometry->boxes, make_ray_generator(scene.camera, s.width, s.height));
  }
  active_labels_ = nullptr;
  frame.stats.time_ms.total = total.ms();
  return frame;
}

}  // namespace sl
