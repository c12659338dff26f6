#include "apps/viewer/progressive.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace sl::viewer {

namespace {

double pixel_fraction(int level) { return std::ldexp(1.0, -level); }

bool known(double ms) { return ms >= 0.0; }

constexpr double kRateWindowSeconds = 1.0;

}  // namespace

float level_scale(int level) { return float(std::sqrt(pixel_fraction(level))); }

std::string level_label(int level) { return level == 0 ? "1" : "1/" + std::to_string(1 << level); }

int level_extent(int full, int level) { return std::max(1, int(std::lround(float(full) * level_scale(level)))); }

ProgressiveLevels::ProgressiveLevels(double budget_ms) : budget_ms_(budget_ms) { ms_.fill(-1.0); }

double ProgressiveLevels::predicted_ms(int level) const {
  if (known(ms_[std::size_t(level)])) return ms_[std::size_t(level)];
  // The two measured levels nearest to `level` (by level index, ties to the finer one).
  int a = -1, b = -1;
  for (int k = 0; k <= kCoarsestLevel; ++k) {
    if (!known(ms_[std::size_t(k)])) continue;
    if (a < 0 || std::abs(k - level) < std::abs(a - level)) {
      b = a;
      a = k;
    } else if (b < 0 || std::abs(k - level) < std::abs(b - level)) {
      b = k;
    }
  }
  if (a < 0) return -1.0;
  const double ta = ms_[std::size_t(a)];
  if (b >= 0) {
    const double tb = ms_[std::size_t(b)];
    const double per_pixel = (ta - tb) / (pixel_fraction(a) - pixel_fraction(b));
    // Noise can make the coarser level look dearer; then the fit says nothing and the proportional
    // rule below decides.
    if (per_pixel > 0.0) return std::max(0.0, ta + per_pixel * (pixel_fraction(level) - pixel_fraction(a)));
  }
  return ta * pixel_fraction(level) / pixel_fraction(a);
}

void ProgressiveLevels::observe(int level, double ms) {
  level = std::clamp(level, 0, kCoarsestLevel);
  ms = std::max(ms, 0.0);
  double& slot = ms_[std::size_t(level)];
  if (known(slot) && slot > 0.0) {
    const double factor = ms / slot;
    for (double& t : ms_) {
      if (known(t)) t *= factor;
    }
  }
  slot = ms;
  for (int k = 0; k <= kCoarsestLevel; ++k) {
    const double limit = budget_ms_ * (k < level_ ? kFinerMargin : 1.0);
    if (predicted_ms(k) <= limit) {
      level_ = k;
      return;
    }
  }
  level_ = kCoarsestLevel;
}

Submission next_submission(bool changed, bool interacting, int last_level, bool worker_idle,
                           bool full_frame_still_loading) {
  if (changed) return Submission::Changed;
  if (!worker_idle) return Submission::None;
  if (last_level > 0) return interacting ? Submission::None : Submission::Refine;
  return full_frame_still_loading ? Submission::Repeat : Submission::None;
}

void FrameRate::tick(double now) {
  times_.push_back(now);
  while (times_.size() > 2 && now - times_.front() > kRateWindowSeconds) times_.pop_front();
}

double FrameRate::fps(double now) const {
  if (times_.size() < 2 || now - times_.back() > kRateWindowSeconds) return 0.0;
  const double span = times_.back() - times_.front();
  return span > 0.0 ? double(times_.size() - 1) / span : 0.0;
}

std::vector<StatRow> progressive_rows(bool progressive, int shown_level, double fps, double budget_ms) {
  char buf[32];
  std::vector<StatRow> rows;
  rows.push_back({"progressive", "", true});
  rows.push_back({"pixels", level_label(shown_level) + (progressive ? "" : " (off)")});
  std::snprintf(buf, sizeof buf, "%.1f", fps);
  rows.push_back({"frames/s", buf});
  if (progressive) {
    std::snprintf(buf, sizeof buf, "%.0f", budget_ms);
    rows.push_back({"budget ms", buf});
  }
  return rows;
}

}  // namespace sl::viewer
