// Progressive rendering: while the view changes (orbit, pan, zoom, a transfer-function or label edit),
// the viewer renders a coarse frame — a fraction of the canvas's pixels, shown stretched — chosen so a
// frame holds a time budget; once the view is still it renders the full-resolution frame, which is the
// image `render` makes for that view. The choice adapts to the measured frame times.
#pragma once

#include <array>
#include <deque>
#include <string>
#include <vector>

#include "apps/viewer/stats_rows.h"

namespace sl::viewer {

// Level k renders 2^-k of the pixels (each axis scaled by 2^(-k/2)); level 0 is full resolution and
// level kCoarsestLevel 1/64 of the pixels (100x75 of an 800x600 canvas).
inline constexpr int kCoarsestLevel = 6;

float level_scale(int level);        // the factor per axis
std::string level_label(int level);  // the pixel fraction: "1", "1/2", "1/4", ...
// The render size of a level for a full-resolution size of w x h (at least 1x1).
int level_extent(int full, int level);

// Picks the level of the next moving frame from the times measured so far: the finest level whose
// predicted time fits the budget. Predictions come from the levels already measured — the time of a
// frame is roughly fixed costs (traversal order, list setup, display) plus a cost per pixel, so with two
// levels measured an affine fit in the pixel count predicts the others; with one, time proportional to
// the pixels (pessimistic for finer levels, so the first step finer is a safe one). A new measurement
// rescales the remembered times of the other levels by the same factor: the view got cheaper or dearer
// as a whole (zoom, a new transfer function).
class ProgressiveLevels {
 public:
  // A level finer than the current one is taken only when predicted within this share of the budget,
  // so measurement noise does not flip between two levels every frame.
  static constexpr double kFinerMargin = 0.85;

  explicit ProgressiveLevels(double budget_ms);

  double budget_ms() const { return budget_ms_; }
  int moving_level() const { return level_; }
  // A frame at `level` took `ms` (render and conversion for display, on the render worker).
  void observe(int level, double ms);
  // The predicted time of a level; negative when nothing is measured yet.
  double predicted_ms(int level) const;

 private:
  double budget_ms_;
  int level_ = 2;  // before any measurement: a quarter of the pixels
  std::array<double, kCoarsestLevel + 1> ms_;  // last known time per level, < 0 unknown
};

// What the interactive loop submits in a UI frame (apps/viewer/ui/viewer.cpp):
// - Changed: the wanted view differs from the last request: render it at the moving level (a queued
//   older job is dropped, latest wins);
// - Refine: the view is unchanged, the user is not dragging, the last request was coarse and the worker
//   is idle (so the coarse frame was shown first): render it at full resolution;
// - Repeat: a full-resolution frame is on screen and out of core it is still loading bricks: render
//   the same view again, each frame more complete (DESIGN.md "Virtual memory");
// - None otherwise (dragging without moving keeps the coarse frame).
enum class Submission { None, Changed, Refine, Repeat };
Submission next_submission(bool changed, bool interacting, int last_level, bool worker_idle,
                           bool full_frame_still_loading);

// Frames shown per second over the last second (the overlay's rate of new images; the UI's own rate
// is ImGui's).
class FrameRate {
 public:
  void tick(double now_seconds);
  double fps(double now_seconds) const;

 private:
  std::deque<double> times_;
};

// The overlay rows for the progressive state: the level of the frame on screen and the rate.
std::vector<StatRow> progressive_rows(bool progressive, int shown_level, double fps, double budget_ms);

}  // namespace sl::viewer
