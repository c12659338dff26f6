#include "core/frame/in_core_renderer.h"

#include <algorithm>
#include <new>
#include <optional>

#include "core/occupancy/block_metadata.h"
#include "core/cast/bricked_volume.h"
#include "core/frame/cast_tiles.h"
#include "core/occupancy/culling.h"
#include "core/util/error.h"
#include "core/occupancy/fine_occupancy.h"
#include "core/occupancy/occupancy_tree.h"
#include "core/occupancy/octree_skip.h"
#include "core/cast/raycast.h"
#include "core/cast/sample_batch.h"

namespace sl {

// What persists between frames besides the pipeline's geometry and lists: metadata (computed once per
// volume and block size, never for a transfer-function or label change), the block classes and the
// tree built from them, and the octree baseline (rebuilt when the classes change).
struct InCoreRenderer::State {
  const Volume* volume = nullptr;
  const Volume* labels = nullptr;
  int block = 0;
  Filter filter = Filter::Linear;  // the metadata's ranges are widened for a B-spline filter
  std::optional<BlockMetadataTable> metadata;
  std::vector<OccupancyClass> classes;
  std::optional<OccupancyTree> tree;
  std::optional<SkipOctree> octree;
  // Fine occupancy inside SparseLeap segments: cell metadata per volume and cell size (like the
  // blocks'), bits per culling input (re-derived from the cached metadata when those change).
  int fine_cell = 0;
  Filter fine_filter = Filter::Linear;
  std::optional<BlockMetadataTable> fine_metadata;
  // The bits of the last two culling inputs: `bench` re-renders every view with its opacity scaled
  // (lists reused) and so alternates between two transfer functions; re-deriving the bits at each
  // switch would cost a visible share of every frame.
  struct FineBits {
    FineOccupancy bits;
    std::uint64_t key = 0;
    bool valid = false;
    VoxelMask voxels;  // for the same inputs, built when first wanted
    bool voxels_valid = false;
    // The pipeline's geometry with its sparse subtrees flattened to their leaves
    // (flatten_sparse_subtrees) and its NON_EMPTY leaf boxes shrunk to `voxels` (tighten_leaf_boxes),
    // made when first wanted for a tree revision.
    std::optional<OccupancyGeometry> tight;
  };
  FineBits fine[2];
  int fine_recent = 0;  // the entry used last
  // The CPU batch's bricked copy of the volume (core/cast/bricked_volume.h), made at its first batched frame.
  const Volume* bricks_volume = nullptr;
  std::optional<BrickedVolume> bricks;
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
                  const BrickedVolume* bricks, Frame& frame) {
  RayCaster<DenseSampler<VT, LT>> caster{params, {grid_of<VT>(scene.volume), grid_of<LT>(scene.labels), bricks}};
  const RayGenerator gen = make_ray_generator(scene.camera, s.width, s.height);
  cast_frame(caster, gen, Box3{vec3(0.0f), scene.volume->desc().extent()}, skip, frame);
}

template <class VT>
void render_labels_typed(const Scene& scene, const RenderSettings& s, const CastParams& p, const SkipInputs& k,
                         const BrickedVolume* bricks, Frame& f) {
  if (!scene.labels) return render_typed<VT, std::uint8_t>(scene, s, p, k, bricks, f);
  dispatch_label(
      scene.labels->type(), [&](auto tag) { render_typed<VT, decltype(tag)>(scene, s, p, k, bricks, f); },
      [] { throw InputError("--labels", "label volume must be of an integer type"); });
}

}  // namespace

// Builds (or reuses) what the method needs: metadata → block classes → occupancy tree, then the
// pipeline's geometry → visibility order → segment lists (SparseLeap) or first-entry / last-exit lists
// (bbox), or the min/max octree (octree). Each stage is timed into the frame's stats.
SkipInputs InCoreRenderer::prepare_skipping(const Scene& scene, const RenderSettings& s, const CastParams& p,
                                            const LabelSet* labels, const RayGenerator& gen, Stats& st) {
  SkipInputs in;
  in.method = s.method;
  if (s.method == SkipMethod::None) return in;
  State& S = *state_;
  Timer t;
  if (!S.metadata || S.volume != scene.volume || S.labels != scene.labels || S.block != s.block ||
      S.filter != s.filter) {
    S = State{};
    S.volume = scene.volume;
    S.labels = scene.labels;
    S.block = s.block;
    S.filter = s.filter;
    const BlockGrid grid = make_block_grid(scene.volume->dims(), scene.volume->desc().spacing, s.block);
    VolumeView lv;
    if (scene.labels) lv = scene.labels->view();
    S.metadata = compute_all_block_metadata(grid, scene.volume->view(), scene.labels ? &lv : nullptr);
    if (s.filter != Filter::Linear) widen_ranges_to_neighbours(*S.metadata);
    st.metadata_computed = S.metadata->blocks.size();
  }
  st.time_ms.metadata = t.ms();
  st.metadata_blocks = S.metadata->blocks.size();

  t = Timer();
  CullParams cull;
  cull.mode = s.mode;
  cull.tf = scene.tf;
  cull.iso = s.iso;
  cull.enabled = (p.label_mask || s.mode == RenderMode::Labels) ? labels : nullptr;
  std::vector<OccupancyClass> classes = classify_blocks(*S.metadata, cull);
  if (!S.tree || classes != S.classes) {
    // A transfer-function or label change lands here: re-cull from cached metadata (DESIGN.md "Occupancy histogram
    // tree").
    S.classes = std::move(classes);
    if (S.tree) {
      S.tree->reclassify(S.classes);
    } else {
      S.tree = OccupancyTree::from_block_classes(S.metadata->grid, S.classes);
    }
    S.octree.reset();
  }
  st.time_ms.tree = t.ms();
  st.tree_nodes = S.tree->node_count();
  st.tree_bytes = S.tree->memory_bytes();

  const OccupancyGeometry& geometry = pipeline_.geometry(*S.tree, st);
  if (s.method == SkipMethod::SparseLeap && s.fine_cell != 0 && s.mode != RenderMode::Iso) {
    in.fine = fine_occupancy(scene, s, cull, st);
  }
  if (s.method == SkipMethod::Octree) {
    t = Timer();
    if (!S.octree) S.octree.emplace(S.metadata->grid, S.classes);
    st.time_ms.tree += t.ms();
    in.octree = S.octree->view();
  } else {
    // Under the voxel mask every caster tests each sample's bit (march_local, the CPU batch), so the
    // lists may come from the leaf boxes shrunk to the mask's set cells: the same samples, shorter spans.
    // Sparse subtrees are flattened to their leaves first, so that their leaves are shrunk too and the
    // lists are built from leaves instead of boxes with EMPTY boxes cut out of them.
    const OccupancyGeometry* tight = nullptr;
    if (s.method == SkipMethod::SparseLeap && s.tight_boxes && in.fine.enabled() && in.fine.voxels.enabled()) {
      std::optional<OccupancyGeometry>& g = S.fine[S.fine_recent].tight;
      if (!g || g->tree_revision != geometry.tree_revision) {
        t = Timer();
        g = tighten_leaf_boxes(*S.tree, flatten_sparse_subtrees(*S.tree, geometry), in.fine.voxels);
        st.time_ms.geometry += t.ms();
      }
      tight = &*g;
    }
    in.lists = pipeline_.lists(*S.tree, s.method, gen, s.gap_eps * p.dt, st, tight);
  }
  return in;
}

FineOccupancyView InCoreRenderer::fine_occupancy(const Scene& scene, const RenderSettings& s, const CullParams& cull,
                                                 Stats& st) {
  State& S = *state_;
  Timer t;
  const VolumeView vv = scene.volume->view();
  const bool mask = s.voxel_mask && s.filter == Filter::Linear &&
                    (s.mode == RenderMode::Dvr || s.mode == RenderMode::Labels) && VoxelMask::supported(vv);
  const int cell = resolve_fine_cell(s.fine_cell, mask);
  if (!S.fine_metadata || S.fine_cell != cell || S.fine_filter != s.filter) {
    const BlockGrid cells = make_block_grid(scene.volume->dims(), scene.volume->desc().spacing, cell);
    VolumeView lv;
    if (scene.labels) lv = scene.labels->view();
    S.fine_metadata = compute_all_block_metadata(cells, scene.volume->view(), scene.labels ? &lv : nullptr);
    if (s.filter != Filter::Linear) widen_ranges_to_neighbours(*S.fine_metadata);
    st.metadata_computed += S.fine_metadata->blocks.size();
    S.fine_cell = cell;
    S.fine_filter = s.filter;
    S.fine[0].valid = S.fine[1].valid = false;
  }
  const std::uint64_t key = cull_key(cull);
  int i = S.fine_recent;
  if (!(S.fine[i].valid && S.fine[i].key == key)) {
    i = 1 - i;
    if (!(S.fine[i].valid && S.fine[i].key == key)) {  // neither: replace the older entry
      S.fine[i].bits.classify(*S.fine_metadata, cull);
      S.fine[i].key = key;
      S.fine[i].valid = true;
      S.fine[i].voxels_valid = false;
    }
    S.fine_recent = i;
  }
  FineOccupancyView view = S.fine[i].bits.view();
  if (mask) {
    if (!S.fine[i].voxels_valid) {
      VolumeView lv;
      if (scene.labels) lv = scene.labels->view();
      S.fine[i].voxels.build(vv, scene.labels ? &lv : nullptr, cull);
      S.fine[i].voxels_valid = true;
      S.fine[i].tight.reset();
    }
    view.voxels = S.fine[i].voxels.view();
    const double cell_voxels = double(cell) * cell * cell;
    const double inside = double(S.fine[i].bits.set_cells()) * cell_voxels;
    view.voxels.fill = inside > 0.0 ? float(std::min(1.0, double(S.fine[i].voxels.set_cells()) / inside)) : 0.0f;
  }
  st.time_ms.metadata += t.ms();
  return view;
}

const BrickedVolume* InCoreRenderer::bricked_volume(const Scene& scene, const CastParams& p, Stats& st) {
  State& S = *state_;
  // Where the batch can run on this volume (BatchMarch::plan's conditions that hold for the whole frame).
  const VoxelType type = scene.volume->type();
  const int elem = type == VoxelType::U8 ? 1 : type == VoxelType::U16 ? 2 : 0;
  const bool batch = p.simd && p.mode == RenderMode::Dvr && !p.lighting.enabled && p.filter == Filter::Linear &&
                     elem > 0 && sample_batch_available();
  if (!batch || !BrickedVolume::supported(scene.volume->dims(), elem)) return nullptr;
  if (S.bricks_volume != scene.volume) {
    Timer t;
    S.bricks.reset();
    S.bricks_volume = scene.volume;
    try {
      S.bricks.emplace(scene.volume->data(), scene.volume->dims(), elem);
    } catch (const std::bad_alloc&) {
      // No room beside the volume: the batch reads its dense rows, as it does without bricks.
    }
    st.time_ms.metadata += t.ms();
  }
  return S.bricks ? &*S.bricks : nullptr;
}

Frame InCoreRenderer::render(const Scene& scene, const RenderSettings& s) {
  validate(scene, s);
  Timer total;
  Frame frame = begin_frame(s);
  LabelSet label_storage;
  const CastParams p = make_cast_params(scene, s, label_storage);
  const LabelSet* labels = scene.enabled ? scene.enabled : (s.mode == RenderMode::Labels ? &label_storage : nullptr);
  const RayGenerator gen = make_ray_generator(scene.camera, s.width, s.height);
  const SkipInputs skip = prepare_skipping(scene, s, p, labels, gen, frame.stats);

  if (caster_) {
    caster_(scene, s, p, skip, frame);
  } else {
    const BrickedVolume* bricks = bricked_volume(scene, p, frame.stats);
    dispatch_voxel(scene.volume->type(),
                   [&](auto tag) { render_labels_typed<decltype(tag)>(scene, s, p, skip, bricks, frame); });
  }
  pipeline_.finish_frame(frame, s, state_->tree ? &*state_->tree : nullptr, gen, total);
  return frame;
}

}  // namespace sl
