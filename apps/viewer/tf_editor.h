// Transfer-function editing as plain state, apart from any window: the operations the viewer's
// editor performs (insert, drag, recolour, delete control points; load/save JSON) and the histogram
// drawn behind it. Kept free of ImGui so every rule is unit-tested (tests/viewer/tf_editor_test.cpp).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/scene/transfer_function.h"
#include "core/scene/volume.h"

namespace sl::viewer {

class TfEditor {
 public:
  // Editing needs two end points to drag; fewer would make "delete" silently change the domain.
  static constexpr std::size_t kMinPoints = 2;

  // `lo`..`hi` is the value domain the editor shows (the data range); it grows to cover `tf`.
  TfEditor(const TransferFunction& tf, float lo, float hi);

  const std::vector<TfPoint>& points() const { return points_; }
  float lo() const { return lo_; }
  float hi() const { return hi_; }
  // Bumped by every change, so the viewer rebuilds the TransferFunction (and the renderer re-culls
  // from cached metadata) only when something changed.
  std::uint64_t revision() const { return revision_; }

  // Inserts a point at `value` (clamped to the domain) after any points of equal value, so the list
  // stays sorted; components are clamped to [0, 1]. Returns the new point's index.
  int insert(float value, const vec4& rgba);
  // Inserts a point on the current curve's colour at `value`, with opacity `alpha` (a click in the
  // editor). Returns its index.
  int insert_at(float value, float alpha);
  // Moves point i. Its value is clamped between its neighbours (order never changes under a drag)
  // and to the domain; alpha to [0, 1]. Returns false for a bad index.
  bool move(int i, float value, float alpha);
  bool set_color(int i, const vec4& rgba);  // clamps every component to [0, 1]
  // Removes point i unless only kMinPoints remain. Returns whether it was removed.
  bool remove(int i);
  // The point nearest to (value, alpha) in screen units: `px_per_value` and `px_per_alpha` scale the
  // axes; -1 when none lies within `radius_px`.
  int nearest(float value, float alpha, float px_per_value, float px_per_alpha, float radius_px) const;

  TransferFunction build() const;
  void set(const TransferFunction& tf);
  // JSON in the format of DESIGN.md "Rendering conventions"; InputError names the file.
  void load(const std::string& path);
  void save(const std::string& path) const;

 private:
  void touch() { ++revision_; }

  std::vector<TfPoint> points_;
  float lo_ = 0.0f;
  float hi_ = 1.0f;
  std::uint64_t revision_ = 0;
};

// Histogram of the volume's values over [lo, hi] in `bins` bins, as log(1 + count) scaled to [0, 1]
// (microscopy data is mostly background: a linear scale would show one spike and nothing else).
std::vector<float> value_histogram(const Volume& v, int bins, float lo, float hi);

// The value domain the editor shows: [0, 255] for u8 data, the data range otherwise.
void data_domain(const Volume& v, float& lo, float& hi);

}  // namespace sl::viewer
