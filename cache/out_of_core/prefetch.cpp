#include "cache/out_of_core/prefetch.h"

#include <algorithm>
#include <utility>

#include "core/util/config.h"

namespace sl {

// What ranks a candidate: the frame's view and, given a next camera, the next view.
struct Prefetch::View {
  const Camera& cam;
  vec3 axis;
  bool motion;
  RayGenerator gen, next;
  LodParams lod;
  vec3 extent;
};

Prefetch::Prefetch(Residency& residency, const LazyOccupancy& occupancy, std::size_t upload_budget)
    : residency_(residency), occupancy_(occupancy), upload_budget_(upload_budget) {}

void Prefetch::promote(std::span<const BrickId> ids) {
  for (const BrickId id : ids) requested_.erase(id);
}

void Prefetch::made_resident(BrickId id) {
  unsampled_.insert(id);
  ++resident_this_frame_;
}

void Prefetch::evicted(BrickId id) {
  unsampled_.erase(id);
  unapplied_.erase(id);  // (its metadata stay cached)
}

bool Prefetch::sampled(BrickId id) {
  if (unsampled_.empty() || !unsampled_.erase(id)) return false;
  if (unapplied_.erase(id)) sampled_unapplied_.push_back(id);
  return true;
}

std::vector<BrickId> Prefetch::take_sampled_unapplied() { return std::exchange(sampled_unapplied_, {}); }

std::optional<std::size_t> Prefetch::budget(const CacheStats& c) const {
  // Within the upload budget and the room the frame leaves; at most a quarter of the cache waits as
  // unused prefetch, so prefetch never churns the cache.
  const std::size_t slots = residency_.cache().slot_count();
  const std::size_t held = unsampled_.size() + requested_.size();
  const std::size_t taken = c.hits + residency_.loader().pending();
  if (held >= slots / 4 || taken >= slots) return std::nullopt;
  return std::min({slots / 4 - held, upload_budget_, slots - taken});
}

// Candidates: the children of bricks this frame used, ranked (motion first, then the nearer the
// view's focus — the centre of the screen — the earlier).
void Prefetch::request(const Camera& camera, const Camera* next, const RenderSettings& s, const LodParams& lod,
                       const RayGenerator& gen, const CacheStats& c, std::uint32_t frame) {
  const std::optional<std::size_t> room = budget(c);
  if (!room) return;
  const bool motion = next != nullptr;
  const View v{camera, glm::normalize(camera.center - camera.eye), motion, gen,
               motion ? make_ray_generator(*next, s.width, s.height) : gen, lod,
               residency_.source().desc().extent()};
  std::vector<std::pair<float, BrickId>> ranked = ranked_candidates(v, frame);
  std::sort(ranked.begin(), ranked.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first < b.first : a.second.bits < b.second.bits;
  });
  std::vector<BrickId> ids;
  for (const auto& [rank, id] : ranked) {
    if (ids.size() >= *room) break;
    if (requested_.count(id) || residency_.page_table().get(id).state() != PageEntry::State::Unmapped ||
        residency_.loader().failed(id)) {
      continue;
    }
    // Only where the tree knows the region holds something: an UNKNOWN region loads nothing for
    // sampling alone (DESIGN.md "Virtual memory"), an EMPTY one needs no data.
    if (!occupancy_.known_non_empty(id)) continue;
    ids.push_back(id);
    requested_.insert(id);
  }
  // The frame's own loads are all in (c.pending == 0), so every id is new to the loader.
  const std::size_t queued = residency_.loader().prefetch(ids);
  SL_CHECK(queued == ids.size());
}

std::vector<std::pair<float, BrickId>> Prefetch::ranked_candidates(const View& v, std::uint32_t frame) const {
  const BrickCache& cache = residency_.cache();
  const BrickLayout& layout = residency_.layout();
  std::vector<std::pair<float, BrickId>> ranked;
  for (std::uint32_t sl = 0; sl < cache.slot_count(); ++sl) {
    if (cache.last_used(sl) != frame) continue;
    const BrickId id = cache.brick_in(sl);
    if (!id.valid() || id.level() == 0) continue;
    const float r = rank(v, id);
    if (r < 0.0f) continue;
    const ivec3 n = layout.bricks(id.level() - 1);
    for (int k = 0; k < 8; ++k) {
      const ivec3 cc = id.coord() * 2 + ivec3(k & 1, (k >> 1) & 1, (k >> 2) & 1);
      if (cc.x >= n.x || cc.y >= n.y || cc.z >= n.z) continue;
      ranked.emplace_back(r, BrickId::pack(id.level() - 1, cc));
    }
  }
  return ranked;
}

// The rank of a used brick's children (negative: not prefetched): in [0, ~2] where the next view
// wants finer than the brick, 10 + the off-axis distance in the central half of the screen.
float Prefetch::rank(const View& v, BrickId id) const {
  const BrickLayout& layout = residency_.layout();
  const vec3 size = layout.level_spacing(id.level()) * float(layout.brick_size);
  const vec3 lo = glm::min(vec3(id.coord()) * size, v.extent), hi = glm::min(lo + size, v.extent);
  const vec3 mid = 0.5f * (lo + hi);
  // Off-axis distance of the brick's centre in units of the screen's half-height.
  float off;
  if (v.gen.orthographic) {
    const vec3 d = mid - v.cam.eye;
    off = glm::length(d - glm::dot(d, v.axis) * v.axis) / v.gen.half_h;
  } else {
    const vec3 d = mid - v.gen.eye;
    const float along = glm::dot(d, v.axis);
    if (along <= 0.0f) return -1.0f;
    off = glm::length(d - along * v.axis) / (along * v.gen.half_h);
  }
  float rank = -1.0f;
  if (v.motion && !v.next.orthographic) {
    // Motion: the next view's level of detail at this brick is finer than the brick.
    const RayGenerator& next = v.next;
    const float t = glm::length(glm::clamp(next.eye, lo, hi) - next.eye);
    const vec3 d = mid - next.eye;
    const float along = glm::dot(d, next.forward);
    if (along > 0.0f && glm::length(d - along * next.forward) < 1.5f * along * next.half_h * std::max(1.0f, next.aspect) &&
        v.lod.level_at(t) < id.level()) {
      rank = off;
    }
  }
  if (rank < 0.0f && off < 0.5f) rank = 10.0f + off;  // the focus: the central half of the screen
  return rank;
}

}  // namespace sl
