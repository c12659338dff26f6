// When an out-of-core view counts as converged (DESIGN.md "Virtual memory": a camera path converges
// over frames; benchmarks report frames-to-convergence): nothing in flight, and the misses either gone
// or the same ones as last frame with nothing left to do about them (bricks that do not fit at a
// pinned level, or failed). A coarsened view is settled only once refining is not worth a try.
#pragma once

#include <cstdint>

#include "core/frame/stats.h"

namespace sl {

// What the frame did besides its cache stats.
struct FrameProgress {
  bool may_refine = false;        // CachePressure::may_refine
  bool pressure_changed = false;  // CachePressure::changed
  bool misses_changed = false;    // resolving the misses requested, mapped or classified something
  bool awaiting = false;          // metadata requested, or prefetched metadata still to apply
};

class Convergence {
 public:
  // Updates the state from frame `frame`; returns the frame it converged at (-1: not converged).
  int update(std::uint32_t frame, const CacheStats& c, const FrameProgress& p);
  bool converged() const { return converged_; }
  // Starts over (the frames now cast something else: the next depth pass): the next frame's misses
  // are compared with nothing.
  void restart();

 private:
  bool converged_ = false;
  int converged_at_ = -1;
  std::uint64_t misses_last_ = 0;
};

}  // namespace sl
