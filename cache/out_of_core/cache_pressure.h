// The level of detail under cache pressure (DESIGN.md "Virtual memory", "Cache pressure is the normal
// case"): a frame never waits and the cache never thrashes. When the bricks a view asks for do not fit,
// the level of detail is coarsened in quarter-octave steps (the pixel footprint is scaled by
// 2^(pressure / 4)), which first coarsens, within each level's distance band, the samples whose voxels
// are smallest on screen — where coarsening costs least; it is refined again one step at a time once
// the view has settled and the finer step was not measured too big.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>

#include "cache/out_of_core/settings.h"
#include "core/cast/raycast.h"
#include "core/frame/frame.h"
#include "core/scene/camera.h"

namespace sl {

// One frame's level of detail.
struct FrameLod {
  LodParams lod;          // what the samples use (coarsened by pressure)
  LodParams footprint;    // the pixel footprint's, without pressure (completeness counts against it)
  float nearest_t = 0.0f; // ray distance to the volume's nearest point
  // Sample spacing. One global grid per frame keeps every method's samples identical (DESIGN.md "Ray
  // casting"); its spacing follows the finest level any sample can use this frame (the level at the
  // volume's nearest point), so a view of a whole terabyte volume does not sample coarse bricks 2^l
  // times more densely than their voxels. Farther, coarser levels take every 2^(l - finest)-th
  // sample of it (LodParams::grid_level = finest): a close-up inside the volume samples its far
  // levels about as densely as their voxels too.
  float step = 0.0f;
};

class CachePressure {
 public:
  CachePressure(int levels, const OutOfCoreSettings& settings);

  // The frame's view: camera, sampling and culling. Pressure measured for one view says nothing of
  // another, so a change allows refining again.
  void begin_frame(const Camera& camera, const RenderSettings& s, std::uint64_t cull_key);
  // `wanted`: the bricks the last frame used plus those it could not load yet; coarsens when they do
  // not fit in `slots`. Refines one step when `settled` (the misses changed nothing and wait for no
  // room) and `loads_done()` (nothing in flight, no metadata awaited). A pinned level never changes.
  void adapt(std::size_t wanted, std::size_t slots, bool settled, const std::function<bool()>& loads_done);
  FrameLod frame_lod(const RayGenerator& gen, const RenderSettings& s, const VolumeDesc& d) const;

  // Quarter-octave steps by which the level of detail is coarsened now (0: none).
  int pressure() const { return pressure_; }
  // Whether this frame's adapt changed it.
  bool changed() const { return changed_; }
  // A coarsened view that refining may still improve (a frame with it is not converged).
  bool may_refine() const { return pinned_ < 0 && pressure_ > 0 && pressure_ - 1 > largest_overflow_step_; }
  // The bricks the view wanted at pressure 0 when they did not fit (0: they did), and their level.
  std::size_t unfit_working_set() const { return unfit_working_set_; }
  int working_set_level(const FrameLod& f) const { return pinned_ >= 0 ? pinned_ : f.footprint.level_at(f.nearest_t); }

 private:
  int levels_;
  int pinned_;
  float lod_bias_;
  int pressure_ = 0;
  bool changed_ = false;
  int largest_overflow_step_ = -1;      // largest step measured too big for the cache in this view
  std::uint64_t view_key_ = 0;
  std::size_t unfit_working_set_ = 0;
};

}  // namespace sl
