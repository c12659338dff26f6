#include "cache/out_of_core/renderer.h"

#include <algorithm>
#include <string>

#include "core/occupancy/culling.h"
#include "core/util/error.h"

namespace sl {

namespace {

std::size_t default_metadata_capacity(const OutOfCoreSettings& settings, std::size_t slots, int block) {
  if (settings.metadata_blocks > 0) return settings.metadata_blocks;
  const std::size_t per = std::size_t(settings.brick / std::max(block, 1));
  return std::max<std::size_t>(16384, 4 * slots * per * per * per);
}

}  // namespace

OutOfCoreRenderer::OutOfCoreRenderer(std::shared_ptr<const VolumeSource> source, const OutOfCoreSettings& settings,
                                     int block, std::unique_ptr<CastDevice> device)
    : source_(std::move(source)),
      settings_(settings),
      block_(block),
      residency_(source_, BrickLayout::make(source_->desc(), settings.brick, source_->name()), settings, block,
                 std::move(device)),
      occupancy_(source_, residency_.layout(), block,
                 default_metadata_capacity(settings, residency_.cache().slot_count(), block)),
      pressure_(residency_.layout().levels, settings),
      prefetch_(residency_, occupancy_, settings.upload_budget),
      tight_(default_metadata_capacity(settings, residency_.cache().slot_count(), block)) {
  if (settings.lod >= layout().levels) {
    throw InputError("--lod", "level " + std::to_string(settings.lod) + " does not exist (the volume has " +
                                  std::to_string(layout().levels) + " levels)");
  }
  residency_.configure_device();
}

OutOfCoreRenderer::~OutOfCoreRenderer() = default;

Frame OutOfCoreRenderer::render(const OutOfCoreScene& scene, const RenderSettings& s) {
  Timer total;
  ++frame_;
  validate(s);
  Frame frame = begin_frame(s);
  Stats& st = frame.stats;
  Timer t;
  begin_culling(scene, s);
  const FrameStart start = start_frame(scene, s);
  MissResolution resolved = answer_last_frame();

  const RayGenerator gen = make_ray_generator(scene.camera, s.width, s.height);
  last_gen_ = gen;
  passes_.begin_frame(DepthPasses::View{scene.camera, s, occupancy_.cull_key()});
  const FrameLod lod = pressure_.frame_lod(gen, s, source_->desc());
  // Before the tree is used: provisional EMPTY where this frame wants a finer level opens now.
  resolved.changed = occupancy_.update_tree(lod.lod, gen) || resolved.changed;
  st.time_ms.metadata = t.ms();
  t = Timer();
  occupancy_.retire(settings_.retire_frames);
  st.time_ms.tree = t.ms();
  occupancy_.fill_stats(st);

  // The slots' voxel masks for this frame's culling, before the lists (tight boxes read them).
  masks_ = residency_.update_masks(cull_, occupancy_.cull_key(), s.filter == Filter::Linear);
  SkipInputs skip = skip_inputs(s, gen, lod, st);
  passes_.apply(skip.pass_t0, skip.pass_t1, skip.rays);
  cast(scene, s, gen, lod, skip, frame);
  fill_cache_stats(start, lod, st);
  update_convergence(resolved, gen, st.cache);
  if (settings_.prefetch) prefetch(scene, s, lod, gen, st.cache);
  pipeline_.finish_frame(frame, s, &occupancy_.tree(), gen, total);
  return frame;
}

void OutOfCoreRenderer::validate(const RenderSettings& s) const {
  if (s.method != SkipMethod::SparseLeap && s.method != SkipMethod::None) {
    throw InputError("--method", std::string("out-of-core rendering supports sparseleap and none, not ") +
                                     to_string(s.method));
  }
  if (s.block != block_) throw InputError("--block", "changed after the out-of-core renderer was created");
  if (s.filter != Filter::Linear && s.method != SkipMethod::None) {
    // The bricks' one-voxel apron bounds each block's metadata to the trilinear footprint.
    throw InputError("--filter", std::string("out of core, ") + to_string(s.filter) +
                                     " reconstruction runs with --method none only (the bricks' one-voxel apron "
                                     "cannot bound a B-spline's footprint for culling)");
  }
}

// Culling inputs; a change re-culls from cached metadata and forgets the Empty mappings made under
// the old culling.
void OutOfCoreRenderer::begin_culling(const OutOfCoreScene& scene, const RenderSettings& s) {
  CullParams cull;
  cull.mode = s.mode;
  cull.tf = scene.tf;
  cull.iso = s.iso;
  cull.enabled = scene.enabled;
  cull_ = cull;
  const bool values_read = s.mode == RenderMode::Iso || s.lighting.enabled;
  const bool recull = occupancy_.begin_frame(frame_, cull);
  if (recull || values_read != empty_values_read_) residency_.forget_culled_empty_pages();
  empty_values_read_ = values_read;
}

OutOfCoreRenderer::FrameStart OutOfCoreRenderer::start_frame(const OutOfCoreScene& scene, const RenderSettings& s) {
  FrameStart start;
  start.evictions = residency_.cache().evictions();
  residency_.begin_frame();
  prefetch_.begin_frame();
  pressure_.begin_frame(scene.camera, s, occupancy_.cull_key());
  start.waiting = residency_.loader().pending() > prefetch_.in_flight();
  return start;
}

// What the last frame left: finished loads become resident, its misses are resolved, the prefetched
// bricks it sampled refine the tree, and the level of detail adapts to what it wanted.
OutOfCoreRenderer::MissResolution OutOfCoreRenderer::answer_last_frame() {
  make_loads_resident();
  MissResolution resolved = resolve_misses();
  for (const BrickId id : prefetch_.take_sampled_unapplied()) {
    occupancy_.apply_cached_metadata(id);
    resolved.changed = true;
  }
  pressure_.adapt(residency_.slots_used_last() + resolved.loadable, residency_.cache().slot_count(),
                  !resolved.changed && resolved.loadable == 0,
                  [&] { return residency_.loader().pending() == 0 && !occupancy_.waiting_for_metadata(); });
  return resolved;
}

SkipInputs OutOfCoreRenderer::skip_inputs(const RenderSettings& s, const RayGenerator& gen, const FrameLod& lod,
                                          Stats& st) {
  SkipInputs skip;
  skip.method = s.method;
  skip.clip = clip_;
  if (s.method == SkipMethod::SparseLeap) {
    const OccupancyTree& tree = occupancy_.tree();
    const OccupancyGeometry& geometry = pipeline_.geometry(tree, st);
    // With the slots' voxel masks, the leaves shrunk to their set cells (tight_boxes.h): sparse
    // subtrees flattened to their leaves first, as in core, so that those leaves shrink too.
    const OccupancyGeometry* tight = nullptr;
    tight_shrunk_ = tight_kept_ = 0;
    if (s.tight_boxes && masks_) {
      const Timer t;
      tight_geometry_ = tight_.tighten(tree, flatten_sparse_subtrees(tree, geometry), layout(), residency_.cache(),
                                       residency_.page_table(), occupancy_.cull_key(), lod.lod, gen);
      tight = &tight_geometry_;
      tight_shrunk_ = tight_.shrunk();
      tight_kept_ = tight_.kept();
      st.time_ms.geometry += t.ms();
    }
    // The short-gap threshold stays in level-0 steps: conservative for any coarser grid.
    const float eps = s.gap_eps * s.step * source_->desc().min_spacing();
    skip.lists = pipeline_.lists(tree, s.method, gen, eps, st, tight);
  }
  return skip;
}

void OutOfCoreRenderer::cast(const OutOfCoreScene& scene, const RenderSettings& s, const RayGenerator& gen,
                             const FrameLod& lod, const SkipInputs& skip, Frame& frame) {
  const VolumeDesc& d = source_->desc();
  CastRequest request;
  request.params = make_cast_params(s, d, *scene.tf, scene.enabled, source_->has_labels(), lod.step, lod.lod);
  residency_.misses().clear();
  request.gen = gen;
  request.vbox = Box3{vec3(0.0f), d.extent()};
  request.skip = skip;
  request.frame = frame_;
  request.host = residency_.host_view(masks_);
  shortfall_.assign(SampleShortfall::kStripes * SampleShortfall::kStride, 0);
  request.host.shortfall.counters = shortfall_.data();
  request.host.shortfall.footprint = lod.footprint;
  request.host.shortfall.eye = gen.eye;
  request.host.shortfall.pressured = pressure_.pressure() > 0;
  residency_.cast(request, frame);
  touch_used_bricks();
}

// The tree nodes and metadata of the bricks the cast sampled stay (LRU retirement and eviction).
void OutOfCoreRenderer::touch_used_bricks() {
  const BrickCache& cache = residency_.cache();
  for (std::uint32_t s = 0; s < cache.slot_count(); ++s) {
    if (cache.last_used(s) != frame_) continue;
    const BrickId id = cache.brick_in(s);
    if (id.valid()) occupancy_.touch_brick(id);
  }
}

void OutOfCoreRenderer::update_convergence(const MissResolution& resolved, const RayGenerator& gen, CacheStats& c) {
  FrameProgress p;
  p.may_refine = pressure_.may_refine();
  p.pressure_changed = pressure_.changed();
  p.misses_changed = resolved.changed;
  p.awaiting = occupancy_.waiting_for_metadata() || prefetch_.applying();
  c.converged_at_frame = convergence_.update(frame_, c, p);
  update_depth_passes(gen, c);
}

// A pinned level that settled short of complete because its bricks do not fit goes on in depth
// passes (depth_passes.h), on a device that casts on the host (the rays' states live there).
void OutOfCoreRenderer::update_depth_passes(const RayGenerator& gen, CacheStats& c) {
  const bool can_split = settings_.lod >= 0 && residency_.device().casts_on_host() && c.failed == 0;
  float t_near = 0.0f, t_far = 0.0f;
  view_depth_range(gen, vec3(0.0f), source_->desc().extent(), t_near, t_far);
  // Ranges are halved down to a quarter of a brick: a thin shell still cuts a layer of bricks, but
  // the thinner it is, the fewer bricks it crosses where it meets the grid obliquely.
  const float min_width = 0.25f * float(layout().brick_size) * source_->desc().min_spacing() *
                          float(1 << std::max(settings_.lod, 0));
  const double share = c.cache_mb > 0 ? c.working_set_mb / c.cache_mb : 0.0;
  if (passes_.end_frame(convergence_.converged(), c.completeness >= 1.0, c.completeness, can_split, t_near, t_far,
                        min_width, share)) {
    convergence_.restart();
  }
  if (passes_.running()) {
    if (passes_.in_progress()) c.converged_at_frame = -1;
    c.completeness = std::min(c.completeness, passes_.completeness());
    c.depth_passes = passes_.count();
    c.depth_pass = passes_.current();
    c.depth_pass_bytes = passes_.bytes();
  }
}

void OutOfCoreRenderer::prefetch(const OutOfCoreScene& scene, const RenderSettings& s, const FrameLod& lod,
                                 const RayGenerator& gen, const CacheStats& c) {
  // Only after a frame that has all it asked for, at its desired level: a pinned level wants nothing
  // finer, and under pressure the finer level does not fit.
  if (settings_.lod >= 0 || pressure_.pressure() > 0 || c.pending > 0 || c.bricks_missing > 0 ||
      occupancy_.waiting_for_metadata()) {
    return;
  }
  prefetch_.request(scene.camera, scene.next_camera, s, lod.lod, gen, c, frame_);
}

}  // namespace sl
