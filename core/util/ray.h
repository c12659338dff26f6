// Rays and axis-aligned boxes in world space, and the one slab test every builder and caster uses
// (CPU segment-list builder, GL fragment shader, kd-restart), so all decide hits identically.
#pragma once

#include "core/util/config.h"
#include "core/util/math.h"

namespace sl {

struct Ray {
  vec3 origin{0.0f};
  vec3 dir{0.0f, 0.0f, 1.0f};  // normalised; t is world distance along it
  // origin + t * dir, per component by name (glm's vec3 temporaries cost more instructions;
  // the same operations in the same order, so the same bits).
  SL_HOST_DEVICE SL_INLINE vec3 at(float t) const {
    return vec3(origin.x + t * dir.x, origin.y + t * dir.y, origin.z + t * dir.z);
  }
};

struct Box3 {
  vec3 lo{0.0f};
  vec3 hi{0.0f};
  SL_HOST_DEVICE bool contains(const vec3& p) const {
    return p.x >= lo.x && p.y >= lo.y && p.z >= lo.z && p.x <= hi.x && p.y <= hi.y && p.z <= hi.z;
  }
};

struct Interval {
  float t0 = 0.0f;
  float t1 = 0.0f;
  SL_HOST_DEVICE bool empty() const { return !(t0 < t1); }
};

// Slab test (Kay–Kajiya). An axis with dir == 0 hits only if the origin lies within the slab there.
// Returns an empty interval (t0 >= t1) on a miss. t may be negative (box behind the origin).
SL_HOST_DEVICE inline Interval intersect(const Ray& r, const Box3& b) {
  float t0 = -3.402823466e+38f;
  float t1 = 3.402823466e+38f;
  for (int a = 0; a < 3; ++a) {
    const float o = r.origin[a];
    const float d = r.dir[a];
    if (d == 0.0f) {
      if (o < b.lo[a] || o > b.hi[a]) return Interval{1.0f, 0.0f};
      continue;
    }
    const float inv = 1.0f / d;
    float u = (b.lo[a] - o) * inv;
    float v = (b.hi[a] - o) * inv;
    if (u > v) {
      const float s = u;
      u = v;
      v = s;
    }
    t0 = u > t0 ? u : t0;
    t1 = v < t1 ? v : t1;
  }
  return Interval{t0, t1};
}

}  // namespace sl
