#include "cache/out_of_core/depth_passes.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace sl {

void DepthPasses::reset() {
  bounds_.clear();
  pass_ = 0;
  finished_ = false;
  committed_ = {};
  frame_ = {};
  completeness_ = 1.0;
}

void DepthPasses::begin_frame(const View& view) {
  if (have_view_ && view == view_) return;
  reset();
  view_ = view;
  have_view_ = true;
}

void DepthPasses::apply(float& t0, float& t1, RayAccum*& rays) {
  if (!running()) return;
  frame_ = committed_;
  t0 = bounds_[std::size_t(pass_)];
  t1 = bounds_[std::size_t(pass_) + 1];
  rays = frame_.data();
}

bool DepthPasses::end_frame(bool settled, bool complete, double completeness, bool can_split, float t_near,
                            float t_far, float min_width, double working_share) {
  if (!settled) return false;
  if (!running()) {
    if (complete || !can_split || !(t_far > t_near)) return false;
    // As many equal ranges as the working set is larger than the cache, and a margin (a range's
    // share of the bricks is not its share of the depth); halved later where that is not enough.
    const int n = working_share > 1.0 ? std::clamp(int(std::ceil(1.25 * working_share)), 2, 16) : 2;
    t_near_ = t_near;
    t_far_ = t_far;
    bounds_.assign(1, 0.0f);
    for (int i = 1; i < n; ++i) bounds_.push_back(t_near + (t_far - t_near) * float(i) / float(n));
    bounds_.push_back(std::numeric_limits<float>::infinity());
    const std::size_t pixels = std::size_t(view_.settings.width) * std::size_t(view_.settings.height);
    committed_.assign(pixels, RayAccum{});
    frame_.assign(pixels, RayAccum{});
    pass_ = 0;
    finished_ = false;
    completeness_ = 1.0;
    return true;
  }
  if (finished_) return false;
  if (!complete && can_split) {
    // The range's bricks do not fit: halve it, when it is wider than the thinnest worth a pass.
    const float lo = pass_ == 0 ? t_near_ : bounds_[std::size_t(pass_)];
    const float hi = pass_ + 1 == count() ? t_far_ : bounds_[std::size_t(pass_) + 1];
    if (hi - lo > 2.0f * min_width) {
      bounds_.insert(bounds_.begin() + pass_ + 1, 0.5f * (lo + hi));
      return true;
    }
  }
  // Settled: complete, or as complete as this cache allows (then the passes go on at that, as one
  // pass would, and the shortfall is kept for the last frame's completeness).
  completeness_ = std::min(completeness_, completeness);
  if (pass_ + 1 == count()) {
    finished_ = true;
    return false;
  }
  committed_.swap(frame_);
  ++pass_;
  return true;
}

void view_depth_range(const RayGenerator& gen, const vec3& lo, const vec3& hi, float& t_near, float& t_far) {
  t_near = std::numeric_limits<float>::max();
  t_far = 0.0f;
  for (int k = 0; k < 8; ++k) {
    const vec3 q((k & 1) ? hi.x : lo.x, (k & 2) ? hi.y : lo.y, (k & 4) ? hi.z : lo.z);
    t_far = std::max(t_far, gen.orthographic ? glm::dot(q - gen.eye, gen.forward) : glm::length(q - gen.eye));
    if (gen.orthographic) t_near = std::min(t_near, glm::dot(q - gen.eye, gen.forward));
  }
  if (!gen.orthographic) t_near = glm::length(glm::clamp(gen.eye, lo, hi) - gen.eye);
  t_near = std::max(t_near, 0.0f);
}

}  // namespace sl
