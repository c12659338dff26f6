#include "apps/viewer/tf_editor.h"

#include <algorithm>
#include <cmath>

#include "core/util/atomic_file.h"
#include "core/util/error.h"

namespace sl::viewer {

namespace {

vec4 clamp01(const vec4& c) { return glm::clamp(c, vec4(0.0f), vec4(1.0f)); }

}  // namespace

TfEditor::TfEditor(const TransferFunction& tf, float lo, float hi) : lo_(lo), hi_(hi) {
  if (!(hi_ > lo_)) hi_ = lo_ + 1.0f;
  set(tf);
}

void TfEditor::set(const TransferFunction& tf) {
  points_ = tf.points();
  // A loaded function may reach past the data range; the domain grows so every point stays editable.
  lo_ = std::min(lo_, points_.front().value);
  hi_ = std::max(hi_, points_.back().value);
  // One point is a constant function; give it a second so both ends can be dragged.
  if (points_.size() < kMinPoints) {
    TfPoint p = points_.front();
    p.value = p.value < hi_ ? hi_ : lo_;
    points_.push_back(p);
    std::sort(points_.begin(), points_.end(), [](const TfPoint& a, const TfPoint& b) { return a.value < b.value; });
  }
  touch();
}

int TfEditor::insert(float value, const vec4& rgba) {
  if (!std::isfinite(value)) value = lo_;
  value = std::clamp(value, lo_, hi_);
  // upper_bound: a new point at an existing value goes after it, so the function's left limit stays.
  const auto it = std::upper_bound(points_.begin(), points_.end(), value,
                                   [](float v, const TfPoint& p) { return v < p.value; });
  const auto at = points_.insert(it, TfPoint{value, clamp01(rgba)});
  touch();
  return int(at - points_.begin());
}

int TfEditor::insert_at(float value, float alpha) {
  vec4 c = build().evaluate(std::clamp(value, lo_, hi_));
  c.a = std::isfinite(alpha) ? alpha : 0.0f;
  return insert(value, c);
}

bool TfEditor::move(int i, float value, float alpha) {
  if (i < 0 || i >= int(points_.size())) return false;
  const float left = i > 0 ? points_[std::size_t(i) - 1].value : lo_;
  const float right = i + 1 < int(points_.size()) ? points_[std::size_t(i) + 1].value : hi_;
  TfPoint& p = points_[std::size_t(i)];
  if (std::isfinite(value)) p.value = std::clamp(value, left, right);
  if (std::isfinite(alpha)) p.rgba.a = std::clamp(alpha, 0.0f, 1.0f);
  touch();
  return true;
}

bool TfEditor::set_color(int i, const vec4& rgba) {
  if (i < 0 || i >= int(points_.size())) return false;
  vec4 c = rgba;
  for (int k = 0; k < 4; ++k) {
    if (!std::isfinite(c[k])) c[k] = points_[std::size_t(i)].rgba[k];
  }
  points_[std::size_t(i)].rgba = clamp01(c);
  touch();
  return true;
}

bool TfEditor::remove(int i) {
  if (i < 0 || i >= int(points_.size()) || points_.size() <= kMinPoints) return false;
  points_.erase(points_.begin() + i);
  touch();
  return true;
}

int TfEditor::nearest(float value, float alpha, float px_per_value, float px_per_alpha, float radius_px) const {
  int best = -1;
  float best_d2 = radius_px * radius_px;
  for (std::size_t i = 0; i < points_.size(); ++i) {
    const float dx = (points_[i].value - value) * px_per_value;
    const float dy = (points_[i].rgba.a - alpha) * px_per_alpha;
    const float d2 = dx * dx + dy * dy;
    // <= so that of coincident points the last wins: it is the one drawn on top.
    if (d2 <= best_d2) {
      best_d2 = d2;
      best = int(i);
    }
  }
  return best;
}

TransferFunction TfEditor::build() const { return TransferFunction(points_, "transfer-function editor"); }

void TfEditor::load(const std::string& path) { set(load_transfer_function(path)); }

void TfEditor::save(const std::string& path) const {
  write_file_atomic(path, transfer_function_to_json(build()) + "\n");
}

std::vector<float> value_histogram(const Volume& v, int bins, float lo, float hi) {
  std::vector<float> h(std::size_t(std::max(bins, 1)), 0.0f);
  if (v.empty() || !(hi > lo)) return h;
  std::vector<std::uint64_t> counts(h.size(), 0);
  const VolumeView view = v.view();
  const float scale = float(h.size()) / (hi - lo);
  const ivec3 d = v.dims();
  for (int z = 0; z < d.z; ++z) {
    for (int y = 0; y < d.y; ++y) {
      for (int x = 0; x < d.x; ++x) {
        const float val = view.value(x, y, z);
        if (!(val >= lo && val <= hi)) continue;  // also drops NaN
        const std::size_t b = std::min(std::size_t((val - lo) * scale), h.size() - 1);
        ++counts[b];
      }
    }
  }
  float top = 0.0f;
  for (std::size_t i = 0; i < h.size(); ++i) {
    h[i] = std::log1p(float(counts[i]));
    top = std::max(top, h[i]);
  }
  if (top > 0.0f) {
    for (float& x : h) x /= top;
  }
  return h;
}

void data_domain(const Volume& v, float& lo, float& hi) {
  if (v.type() == VoxelType::U8) {
    lo = 0.0f;
    hi = 255.0f;
    return;
  }
  const vec2 r = value_range(v);
  lo = r.x;
  hi = r.y > r.x ? r.y : r.x + 1.0f;
}

}  // namespace sl::viewer
