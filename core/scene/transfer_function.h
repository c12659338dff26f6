// Piecewise-linear RGBA transfer function (DESIGN.md "Ray casting"): control points, the sampled table casters
// read, and the O(1) max-opacity range query that culling uses (DESIGN.md "Occupancy histogram tree").
#pragma once

#include <string>
#include <vector>

#include "core/util/config.h"
#include "core/util/math.h"

namespace sl {

struct TfPoint {
  float value = 0.0f;
  vec4 rgba{0.0f};  // components in [0, 1], not premultiplied
};

// Plain view of a sampled table: entry i holds the function at vmin + i / inv_step.
struct TransferFunctionView {
  const vec4* table = nullptr;
  int size = 0;
  float vmin = 0.0f;
  float inv_step = 0.0f;  // entries per data unit (0 for a constant function)

  // Table position of value v: entry i and the fraction f towards entry i + 1.
  struct Coord {
    int i;
    float f;
  };
  // Non-finite samples: -Inf and +Inf read the table's ends; NaN (and Inf * 0 of a constant function)
  // reads entry 0, the low end, like -Inf. The comparisons are ordered so a NaN x fails `x > 0` and
  // becomes 0 at no extra cost (int(NaN) would index far outside the table); finite values map exactly
  // as before.
  SL_HOST_DEVICE SL_INLINE Coord coord(float v) const {
    float x = (v - vmin) * inv_step;
    const float last = float(size - 1);
    x = x > 0.0f ? (x < last ? x : last) : 0.0f;
    int i = int(x);
    if (i > size - 2) i = size - 2;
    return {i, x - float(i)};
  }
  // The casters read opacity first and colour only where it is non-zero (most samples of sparse data
  // are transparent). Component for component the same arithmetic as lookup().
  SL_HOST_DEVICE SL_INLINE float alpha_at(Coord c) const {
    return table[c.i].w + c.f * (table[c.i + 1].w - table[c.i].w);
  }
  SL_HOST_DEVICE SL_INLINE vec3 rgb_at(Coord c) const {
    const vec3 a(table[c.i]), b(table[c.i + 1]);
    return a + c.f * (b - a);
  }
  SL_HOST_DEVICE SL_INLINE vec4 lookup(float v) const {
    const Coord c = coord(v);
    return table[c.i] + c.f * (table[c.i + 1] - table[c.i]);
  }
};

class TransferFunction {
 public:
  static constexpr int kTableSize = 4096;

  TransferFunction() = default;
  // Throws InputError(origin, ...) for no points, values not ascending, components outside [0, 1].
  TransferFunction(std::vector<TfPoint> points, const std::string& origin = "transfer function");

  const std::vector<TfPoint>& points() const { return points_; }
  float vmin() const { return points_.front().value; }
  float vmax() const { return points_.back().value; }

  // The exact piecewise-linear function (for tests and editors).
  vec4 evaluate(float v) const;
  // Table with opacity corrected for a sample distance of `step` times the reference distance:
  // α' = 1 − (1 − α)^step. step = 1 gives the uncorrected table.
  const std::vector<vec4>& table(float step) const;
  TransferFunctionView view(float step) const;

  // Largest table opacity over data values [lo, hi] (conservative for linear interpolation between
  // table entries); O(1) by a sparse range-maximum table. A NaN bound (a block whose min/max started
  // from a NaN voxel) means the range is unknown: the whole table, so culling stays conservative.
  float max_opacity(float lo, float hi) const;

  // Multiplies every opacity by s (clamped to 1); rebuilds the tables.
  TransferFunction scaled_opacity(float s) const;

 private:
  void build();

  std::vector<TfPoint> points_;
  std::vector<vec4> table_;                     // uncorrected, kTableSize entries
  std::vector<std::vector<float>> range_max_;   // range_max_[k][i] = max alpha over [i, i + 2^k)
  mutable float corrected_step_ = -1.0f;
  mutable std::vector<vec4> corrected_;
};

// Reads `{"points":[{"value":v,"rgba":[r,g,b,a]},...]}`; InputError names the file.
TransferFunction load_transfer_function(const std::string& path);
TransferFunction parse_transfer_function(const std::string& json_text, const std::string& origin);
std::string transfer_function_to_json(const TransferFunction& tf);

// Sensible defaults: for neurite-like u8 data (0 = background), and a ramp over [lo, hi].
TransferFunction default_transfer_function(float lo, float hi);

}  // namespace sl
