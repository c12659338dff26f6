#include "core/scene/transfer_function.h"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>

#include "core/util/error.h"
#include "core/util/json_util.h"

namespace sl {

TransferFunction::TransferFunction(std::vector<TfPoint> points, const std::string& origin)
    : points_(std::move(points)) {
  if (points_.empty()) throw InputError(origin, "transfer function has no points");
  for (size_t i = 0; i < points_.size(); ++i) {
    if (!std::isfinite(points_[i].value)) throw InputError(origin, "point value is not finite");
    if (i > 0 && points_[i].value < points_[i - 1].value) {
      throw InputError(origin, "point values must be ascending (point " + std::to_string(i) + ")");
    }
    for (int c = 0; c < 4; ++c) {
      const float x = points_[i].rgba[c];
      if (!(x >= 0.0f && x <= 1.0f)) {
        throw InputError(origin, "rgba components must be in [0, 1] (point " + std::to_string(i) + ")");
      }
    }
  }
  build();
}

vec4 TransferFunction::evaluate(float v) const {
  if (v <= points_.front().value) return points_.front().rgba;
  if (v >= points_.back().value) return points_.back().rgba;
  // First point with value > v; v lies in [p[i-1], p[i]).
  const auto it = std::upper_bound(points_.begin(), points_.end(), v,
                                   [](float x, const TfPoint& p) { return x < p.value; });
  const TfPoint& b = *it;
  const TfPoint& a = *(it - 1);
  const float span = b.value - a.value;
  const float f = span > 0.0f ? (v - a.value) / span : 1.0f;
  return a.rgba + f * (b.rgba - a.rgba);
}

void TransferFunction::build() {
  table_.resize(kTableSize);
  const float lo = vmin();
  const float hi = vmax();
  for (int i = 0; i < kTableSize; ++i) {
    const float v = hi > lo ? lo + (hi - lo) * float(i) / float(kTableSize - 1) : lo;
    table_[i] = evaluate(v);
  }
  // Sparse table for O(1) range maximum of opacity.
  range_max_.clear();
  std::vector<float> level(kTableSize);
  for (int i = 0; i < kTableSize; ++i) level[i] = table_[i].a;
  range_max_.push_back(level);
  for (int w = 1; 2 * w <= kTableSize; w *= 2) {
    const auto& prev = range_max_.back();
    std::vector<float> next(kTableSize - 2 * w + 1);
    for (size_t i = 0; i < next.size(); ++i) next[i] = std::max(prev[i], prev[i + w]);
    range_max_.push_back(std::move(next));
  }
  corrected_step_ = -1.0f;
}

const std::vector<vec4>& TransferFunction::table(float step) const {
  if (step == 1.0f) return table_;
  if (corrected_step_ != step) {
    corrected_ = table_;
    for (auto& e : corrected_) e.a = 1.0f - std::pow(1.0f - e.a, step);
    corrected_step_ = step;
  }
  return corrected_;
}

TransferFunctionView TransferFunction::view(float step) const {
  const auto& t = table(step);
  TransferFunctionView v;
  v.table = t.data();
  v.size = int(t.size());
  v.vmin = vmin();
  v.inv_step = vmax() > vmin() ? float(kTableSize - 1) / (vmax() - vmin()) : 0.0f;
  return v;
}

float TransferFunction::max_opacity(float lo, float hi) const {
  if (std::isnan(lo) || std::isnan(hi)) {
    lo = vmin();
    hi = vmax();
  }
  if (hi < lo) std::swap(lo, hi);
  const float scale = vmax() > vmin() ? float(kTableSize - 1) / (vmax() - vmin()) : 0.0f;
  auto to_index = [&](float v, bool up) {
    float x = (v - vmin()) * scale;
    x = x > 0.0f ? std::min(x, float(kTableSize - 1)) : 0.0f;  // NaN (Inf * 0 of a constant function) -> 0
    return up ? int(std::ceil(x)) : int(std::floor(x));
  };
  const int i0 = to_index(lo, false);
  const int i1 = to_index(hi, true);
  const int len = i1 - i0 + 1;
  int k = 0;
  while ((2 << k) <= len) ++k;
  return std::max(range_max_[k][i0], range_max_[k][i1 - (1 << k) + 1]);
}

TransferFunction TransferFunction::scaled_opacity(float s) const {
  std::vector<TfPoint> p = points_;
  for (auto& q : p) q.rgba.a = std::clamp(q.rgba.a * s, 0.0f, 1.0f);
  return TransferFunction(std::move(p));
}

TransferFunction parse_transfer_function(const std::string& text, const std::string& origin) {
  const nlohmann::json j = parse_json(text, origin);
  if (!j.is_object() || !j.contains("points") || !j["points"].is_array()) {
    throw InputError(origin, "expected an object with a \"points\" array");
  }
  std::vector<TfPoint> pts;
  for (const auto& p : j["points"]) {
    if (!p.is_object()) throw InputError(origin, "each point must be an object");
    TfPoint q;
    q.value = json_number(p, "value", origin);
    if (!p.contains("rgba") || !p["rgba"].is_array() || p["rgba"].size() != 4) {
      throw InputError(origin, "each point needs \"rgba\": an array of 4 numbers");
    }
    for (int c = 0; c < 4; ++c) {
      if (!p["rgba"][c].is_number()) throw InputError(origin, "\"rgba\" must hold numbers");
      q.rgba[c] = p["rgba"][c].get<float>();
    }
    pts.push_back(q);
  }
  return TransferFunction(std::move(pts), origin);
}

TransferFunction load_transfer_function(const std::string& path) {
  return parse_transfer_function(read_file_text(path), path);
}

std::string transfer_function_to_json(const TransferFunction& tf) {
  nlohmann::json j;
  j["points"] = nlohmann::json::array();
  for (const auto& p : tf.points()) {
    j["points"].push_back({{"value", p.value}, {"rgba", {p.rgba.r, p.rgba.g, p.rgba.b, p.rgba.a}}});
  }
  return j.dump(2);
}

TransferFunction default_transfer_function(float lo, float hi) {
  const float w = hi - lo;
  return TransferFunction({
      {lo, {0.0f, 0.0f, 0.0f, 0.0f}},
      {lo + 0.25f * w, {0.0f, 0.0f, 0.0f, 0.0f}},
      {lo + 0.45f * w, {0.85f, 0.35f, 0.15f, 0.08f}},
      {lo + 0.75f * w, {1.0f, 0.8f, 0.45f, 0.45f}},
      {hi, {1.0f, 1.0f, 0.95f, 0.8f}},
  });
}

}  // namespace sl
