// The out-of-core renderer's answer to what the last frame left (renderer.h): the bricks the loader
// finished become resident, and the misses the cast reported are resolved into loads.
#include <algorithm>
#include <limits>
#include <utility>
#include <vector>

#include "cache/out_of_core/renderer.h"
#include "core/util/parallel.h"

namespace sl {

void OutOfCoreRenderer::make_loads_resident() {
  LoaderBatch batch = residency_.loader().collect(settings_.upload_budget);
  for (const BrickFailure& f : batch.failures) {
    // A failed brick (permanent, or out of retries) is never requested again. It stays unmapped:
    // sampled from its finest resident ancestor, or as missing, and counted short of complete, so a
    // frame with lost data never claims completeness 1.
    residency_.report_failure(f);
    occupancy_.mark_unreadable(f.id);
    prefetch_.forget_failed(f.id);
  }
  // The metadata the bricks bring (a source's bounds can mean synthesising or reading the level-0
  // voxels below a block): computed on all cores, then applied in the bricks' order, which is all
  // that touches the occupancy.
  const std::size_t n = batch.bricks.size();
  std::vector<char> wanted(n);
  for (std::size_t i = 0; i < n; ++i) {
    const BrickId id = batch.bricks[i].id;
    wanted[i] = occupancy_.metadata_requested(id) || !occupancy_.has_metadata(id);
  }
  std::vector<LazyOccupancy::BrickMetadata> computed(n);
  parallel_for(std::size_t(0), n, [&](std::size_t i) {
    if (wanted[i]) computed[i] = occupancy_.brick_metadata(batch.bricks[i]);
  });
  for (std::size_t i = 0; i < n; ++i) take_loaded_brick(std::move(batch.bricks[i]), wanted[i] ? &computed[i] : nullptr);
  residency_.finish_uploads();
}

void OutOfCoreRenderer::take_loaded_brick(LoadedBrick&& b, LazyOccupancy::BrickMetadata* computed) {
  const BrickId id = b.id;
  const bool prefetched = prefetch_.take_requested(id);
  if (occupancy_.take_metadata_request(id)) {
    occupancy_.compute_metadata(b, /*apply=*/true, computed);
  } else if (prefetched && !occupancy_.has_metadata(id)) {
    // Chosen under a known NON_EMPTY region: its own metadata will refine the tree there, as a
    // frame's load of it would (LazyOccupancy::refined_by_loading) — once a frame samples it.
    occupancy_.compute_metadata(b, /*apply=*/false, computed);
    prefetch_.metadata_unapplied(id);
  }
  const Residency::Placement p = residency_.place(std::move(b), frame_, prefetched);
  if (p.evicted.valid()) prefetch_.evicted(p.evicted);
  if (p.placed && prefetched) prefetch_.made_resident(id);
}

// Paper §8.2: each missed brick means what the occupancy tree says of its region. Unknown → its
// metadata (from cache, or by loading the brick), then cull and grow; known non-empty and not
// resident → load; known empty → map it Empty (served as 0), unless its values reach the image (iso
// mode, lighting: empty_values_read_), then load it. Unknown regions never load data for sampling alone.
OutOfCoreRenderer::MissResolution OutOfCoreRenderer::resolve_misses() {
  MissResolution res;
  MissLoads loads;
  for (const BrickId id : residency_.misses().drain()) resolve_miss(id, res, loads);
  request_loads(loads, res);
  return res;
}

void OutOfCoreRenderer::resolve_miss(BrickId id, MissResolution& res, MissLoads& loads) {
  if (residency_.loader().failed(id)) return;
  const OccupancyClass cls = occupancy_.brick_class(id);
  if (cls == OccupancyClass::Unknown) {
    // Cached metadata regrow a retired or re-culled region without touching the data. A load asked
    // for before is named again: this frame's priority orders it (the loader queues it once).
    if (!occupancy_.apply_cached_metadata_if_complete(id)) {
      occupancy_.request_metadata(id);
      loads.metadata.push_back(id);
    }
    return;
  }
  const PageEntry e = residency_.page_table().get(id);
  if (cls == OccupancyClass::Empty && !empty_values_read_) {
    if (!e.is_resident() && e.state() != PageEntry::State::Empty) {
      residency_.map_culled_empty(id);
      res.changed = true;
    }
  } else if (!e.is_resident()) {
    loads.data.push_back(id);
    loads.refines.push_back(occupancy_.refined_by_loading(id));
  }
}

// Where a brick stands in the frame that missed it: the distance from the eye to its box along the
// view (perspective: to the box's nearest point; orthographic: depth of its nearest corner). Nearer
// first: they occlude what lies behind, so the picture fills front to back, and a ray that ends in
// them never asks for the bricks behind.
float OutOfCoreRenderer::load_priority(BrickId id) const {
  const WorldBox b = layout().brick_box(id);
  if (!last_gen_.orthographic) return glm::length(glm::clamp(last_gen_.eye, b.lo, b.hi) - last_gen_.eye);
  float depth = std::numeric_limits<float>::max();
  for (int c = 0; c < 8; ++c) {
    const vec3 p((c & 1) ? b.hi.x : b.lo.x, (c & 2) ? b.hi.y : b.lo.y, (c & 4) ? b.hi.z : b.lo.z);
    depth = std::min(depth, glm::dot(p - last_gen_.eye, last_gen_.forward));
  }
  return depth;
}

// In the order the frame needs them (load_priority; ties by id, so the order is deterministic).
void OutOfCoreRenderer::order_by_priority(std::vector<BrickId>& ids, std::vector<bool>* with) const {
  std::vector<std::pair<float, std::size_t>> keyed(ids.size());
  for (std::size_t i = 0; i < ids.size(); ++i) keyed[i] = {load_priority(ids[i]), i};
  std::sort(keyed.begin(), keyed.end(), [&](const auto& a, const auto& b) {
    return a.first != b.first ? a.first < b.first : ids[a.second].bits < ids[b.second].bits;
  });
  std::vector<BrickId> sorted(ids.size());
  std::vector<bool> sorted_with(with ? ids.size() : 0);
  for (std::size_t i = 0; i < keyed.size(); ++i) {
    sorted[i] = ids[keyed[i].second];
    if (with) sorted_with[i] = (*with)[keyed[i].second];
  }
  ids.swap(sorted);
  if (with) with->swap(sorted_with);
}

// Metadata loads are always made: culling needs them. Data loads only as far as there is room: a
// brick loaded without a slot would be dropped and requested again every frame (loader work for
// nothing, and no progress). Each kind in the frame's priority, metadata first.
void OutOfCoreRenderer::request_loads(MissLoads& loads, MissResolution& res) {
  order_by_priority(loads.metadata, nullptr);
  order_by_priority(loads.data, &loads.refines);
  res.loadable = loads.data.size();
  const std::size_t n = std::min(loads.data.size(), residency_.free_slots_for_loads());
  std::vector<BrickId>& ids = loads.metadata;
  ids.insert(ids.end(), loads.data.begin(), loads.data.begin() + std::ptrdiff_t(n));
  for (std::size_t i = 0; i < n; ++i) {
    if (loads.refines[i]) occupancy_.request_metadata(loads.data[i]);
  }
  prefetch_.promote(ids);  // the loader promotes them
  res.requested = residency_.loader().request(ids);
  res.changed = res.changed || res.requested > 0;
}

}  // namespace sl
