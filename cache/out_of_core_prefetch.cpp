// Prefetch (issue 14): after a frame that has every brick it asked for, the out-of-core renderer
// loads, within the upload budget and the cache's spare room, the next-finer level around the view's
// focus and the bricks the next view (along the camera's motion) will want finer. Prefetched bricks
// wait at the lowest priority in the loader, never evict a brick the last frame used, and are the
// first to go when a frame needs the room (out_of_core.cpp, upload).
#include <algorithm>

#include "cache/out_of_core.h"
#include "core/util/config.h"

namespace sl {

void OutOfCoreRenderer::prefetch(const OutOfCoreScene& scene, const RenderSettings& s, const LodParams& lod,
                                 const RayGenerator& gen, const CacheStats& c) {
  // Only after a frame that has all it asked for, at its desired level: a pinned level wants nothing
  // finer, and under pressure the finer level does not fit.
  if (settings_.lod >= 0 || pressure_ > 0 || c.pending > 0 || c.bricks_missing > 0 || !metadata_pending_.empty()) {
    return;
  }
  // Within the upload budget and the room the frame leaves; at most a quarter of the cache waits
  // as unused prefetch, so prefetch never churns the cache.
  const std::size_t slots = cache_.slot_count();
  const std::size_t held = prefetched_unused_.size() + prefetch_requested_.size();
  const std::size_t taken = c.hits + loader_.pending();
  if (held >= slots / 4 || taken >= slots) return;
  const std::size_t budget = std::min({slots / 4 - held, settings_.upload_budget, slots - taken});

  const vec3 extent = source_->desc().extent();
  const Camera& cam = scene.camera;
  const vec3 axis = glm::normalize(cam.center - cam.eye);
  const bool motion = scene.next_camera != nullptr;
  const RayGenerator next = motion ? make_ray_generator(*scene.next_camera, s.width, s.height) : gen;
  // Candidates: the children of bricks this frame used, ranked (motion first, then the nearer the
  // view's focus — the centre of the screen — the earlier).
  std::vector<std::pair<float, BrickId>> ranked;
  for (std::uint32_t sl = 0; sl < slots; ++sl) {
    if (cache_.last_used(sl) != frame_) continue;
    const BrickId id = cache_.brick_in(sl);
    if (!id.valid() || id.level() == 0) continue;
    const vec3 size = layout_.level_spacing(id.level()) * float(layout_.brick_size);
    const vec3 lo = glm::min(vec3(id.coord()) * size, extent), hi = glm::min(lo + size, extent);
    const vec3 mid = 0.5f * (lo + hi);
    // Off-axis distance of the brick's centre in units of the screen's half-height.
    float off;
    if (gen.orthographic) {
      const vec3 d = mid - cam.eye;
      off = glm::length(d - glm::dot(d, axis) * axis) / gen.half_h;
    } else {
      const vec3 d = mid - gen.eye;
      const float along = glm::dot(d, axis);
      if (along <= 0.0f) continue;
      off = glm::length(d - along * axis) / (along * gen.half_h);
    }
    float rank = -1.0f;
    if (motion && !next.orthographic) {
      // Motion: the next view's level of detail at this brick is finer than the brick.
      const float t = glm::length(glm::clamp(next.eye, lo, hi) - next.eye);
      const vec3 d = mid - next.eye;
      const float along = glm::dot(d, next.forward);
      if (along > 0.0f && glm::length(d - along * next.forward) < 1.5f * along * next.half_h * std::max(1.0f, next.aspect) &&
          lod.level_at(t) < id.level()) {
        rank = off;  // in [0, ~2]
      }
    }
    if (rank < 0.0f && off < 0.5f) rank = 10.0f + off;  // the focus: the central half of the screen
    if (rank < 0.0f) continue;
    const ivec3 n = layout_.bricks(id.level() - 1);
    for (int k = 0; k < 8; ++k) {
      const ivec3 cc = id.coord() * 2 + ivec3(k & 1, (k >> 1) & 1, (k >> 2) & 1);
      if (cc.x >= n.x || cc.y >= n.y || cc.z >= n.z) continue;
      ranked.emplace_back(rank, BrickId::pack(id.level() - 1, cc));
    }
  }
  std::sort(ranked.begin(), ranked.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first < b.first : a.second.bits < b.second.bits;
  });
  std::vector<BrickId> ids;
  for (const auto& [rank, id] : ranked) {
    if (ids.size() >= budget) break;
    if (prefetch_requested_.count(id) || page_table_.get(id).state() != PageEntry::State::Unmapped ||
        loader_.failed(id)) {
      continue;
    }
    // Only where the tree knows the region holds something: an UNKNOWN region loads nothing for
    // sampling alone (DESIGN.md §4), an EMPTY one needs no data.
    const std::uint32_t nd = node_for_brick(id);
    const OccupancyNode& node = tree_.node(nd);
    const OccupancyClass cls = tree_.is_leaf(nd) ? node.cls : conservative_class(node.count);
    if (cls != OccupancyClass::NonEmpty || node.count[int(OccupancyClass::Unknown)] > 0) continue;
    ids.push_back(id);
    prefetch_requested_.insert(id);
  }
  // The frame's own loads are all in (c.pending == 0), so every id is new to the loader.
  const std::size_t queued = loader_.prefetch(ids);
  SL_CHECK(queued == ids.size());
}

}  // namespace sl
