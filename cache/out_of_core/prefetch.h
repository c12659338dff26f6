// Prefetch (OutOfCoreSettings::prefetch): after a frame that has every brick it asked for, the
// out-of-core renderer loads, within the upload budget and the cache's spare room, the next-finer
// level around the view's focus and the bricks the next view (along the camera's motion) will want
// finer. Prefetched bricks wait at the lowest priority in the loader, never evict a brick the last
// frame used, and are the first to go when a frame needs the room (Residency::place). Their metadata
// refine the tree only once a frame samples them: refined at once, the tree would open UNKNOWN
// siblings in a view that converged without them.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <unordered_set>
#include <vector>

#include "cache/brick.h"
#include "cache/out_of_core/lazy_occupancy.h"
#include "cache/out_of_core/residency.h"
#include "core/cast/raycast.h"
#include "core/frame/frame.h"
#include "core/scene/camera.h"

namespace sl {

class Prefetch {
 public:
  Prefetch(Residency& residency, const LazyOccupancy& occupancy, std::size_t upload_budget);

  void begin_frame() { resident_this_frame_ = 0; }
  // Requests the prefetches after a complete frame (c: its cache stats; next: the camera expected
  // next, or null).
  void request(const Camera& camera, const Camera* next, const RenderSettings& s, const LodParams& lod,
               const RayGenerator& gen, const CacheStats& c, std::uint32_t frame);

  // Whether a collected brick was a prefetch (and forgets the request).
  bool take_requested(BrickId id) { return requested_.erase(id) > 0; }
  // The frame's own request of a queued prefetch makes it demand (the loader promotes it).
  void promote(std::span<const BrickId> ids);
  void forget_failed(BrickId id) { requested_.erase(id); }
  // A prefetched brick made resident; its metadata, when computed, wait for a frame that samples it.
  void made_resident(BrickId id);
  void metadata_unapplied(BrickId id) { unapplied_.insert(id); }
  void evicted(BrickId id);
  // A slot this frame sampled holds `id`: returns whether it was a prefetch not sampled before.
  bool sampled(BrickId id);
  // The prefetched bricks sampled last frame whose metadata now refine the tree.
  std::vector<BrickId> take_sampled_unapplied();
  bool applying() const { return !sampled_unapplied_.empty(); }

  std::size_t in_flight() const { return requested_.size(); }
  std::uint64_t resident_this_frame() const { return resident_this_frame_; }

 private:
  struct View;
  std::optional<std::size_t> budget(const CacheStats& c) const;  // none: nothing to prefetch now
  std::vector<std::pair<float, BrickId>> ranked_candidates(const View& v, std::uint32_t frame) const;
  float rank(const View& v, BrickId id) const;

  Residency& residency_;
  const LazyOccupancy& occupancy_;
  std::size_t upload_budget_;
  // Requested and not yet collected, and made resident but not sampled yet.
  std::unordered_set<BrickId, BrickIdHash> requested_, unsampled_;
  // Resident prefetches whose metadata are cached but not yet in the tree; those a frame sampled, to
  // apply at the next frame.
  std::unordered_set<BrickId, BrickIdHash> unapplied_;
  std::vector<BrickId> sampled_unapplied_;
  std::uint64_t resident_this_frame_ = 0;
};

}  // namespace sl
