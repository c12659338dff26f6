#include "cache/out_of_core/convergence.h"

namespace sl {

void Convergence::restart() {
  converged_ = false;
  converged_at_ = -1;
  misses_last_ = ~std::uint64_t(0);
}

int Convergence::update(std::uint32_t frame, const CacheStats& c, const FrameProgress& p) {
  const bool settled = !p.may_refine && (c.misses == 0 || (!p.misses_changed && c.loads == 0 &&
                                                           c.misses == misses_last_ && !p.pressure_changed));
  misses_last_ = c.misses;
  converged_ = settled && c.pending == 0 && !p.awaiting;
  if (!converged_) {
    converged_at_ = -1;
  } else if (converged_at_ < 0) {
    converged_at_ = int(frame);
  }
  return converged_at_;
}

}  // namespace sl
