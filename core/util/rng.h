// SplitMix64 (Steele, Lea and Flood 2014; the reference is Vigna's splitmix64.c): tiny, fast and fully
// specified, so a seed means the same data set, label subset and test case on every platform and
// compiler. The one copy every generator uses: changing it changes every generated volume.
#pragma once

#include <cmath>
#include <cstdint>

#include "core/util/config.h"
#include "core/util/math.h"

namespace sl {

inline constexpr std::uint64_t kSplitMixGamma = 0x9E3779B97F4A7C15ull;  // 2^64 / golden ratio, odd

// The output function (a bijective 64-bit mix): also a good hash of a 64-bit key.
SL_HOST_DEVICE constexpr std::uint64_t splitmix64_mix(std::uint64_t z) {
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

// The first output of a generator in state x: splitmix64.c's next() as a pure function.
SL_HOST_DEVICE constexpr std::uint64_t splitmix64(std::uint64_t x) { return splitmix64_mix(x + kSplitMixGamma); }

class SplitMix64 {
 public:
  explicit constexpr SplitMix64(std::uint64_t state) : s_(state) {}
  constexpr std::uint64_t next() { return splitmix64_mix(s_ += kSplitMixGamma); }
  // [0, 1) in steps of 2^-24: every value exactly representable as a float.
  float uniform() { return float(next() >> 40) * 0x1p-24f; }
  float uniform(float a, float b) { return a + (b - a) * uniform(); }
  // [0, 1) in steps of 2^-53.
  double uniform_double() { return double(next() >> 11) * 0x1.0p-53; }
  // Uniform in the unit ball: rejection sampling keeps it isotropic without transcendental functions.
  vec3 in_ball() {
    for (;;) {
      const vec3 v(uniform(-1, 1), uniform(-1, 1), uniform(-1, 1));
      if (glm::dot(v, v) <= 1.0f) return v;
    }
  }
  // Uniform on the unit sphere.
  vec3 unit() {
    for (;;) {
      const vec3 v = in_ball();
      const float l2 = glm::dot(v, v);
      if (l2 > 1e-4f) return v / std::sqrt(l2);
    }
  }

 private:
  std::uint64_t s_;
};

}  // namespace sl
