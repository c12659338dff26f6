// Sort-last distributed rendering (DESIGN.md "Beyond one machine"): a rank casts the same rays on the same global
// per-ray sample grid t_k = t_entry + k·dt as a single process, and takes exactly the samples whose
// positions fall in its region. Regions are half-open boxes [lo, hi) whose outer faces lie at
// infinity, so every sample of the grid belongs to exactly one region of a k-d split; each rank
// composites its samples front to back, and the ordered "over" of the ranks' partial RGBA then equals
// the single-process sum up to float rounding. SL_HOST_DEVICE: the CPU caster and the CUDA kernels
// (core/cast/cast_pixel.h) clip with this one function.
#pragma once

#include <cmath>

#include "core/util/config.h"
#include "core/util/math.h"
#include "core/util/ray.h"

namespace sl {

struct SampleClip {
  bool enabled = false;  // false: every sample (single process)
  vec3 lo{0.0f};         // half-open [lo, hi) per axis; ±infinity on the region's outer faces
  vec3 hi{0.0f};

  SL_HOST_DEVICE SL_INLINE bool contains(const vec3& p) const {
    return p.x >= lo.x && p.y >= lo.y && p.z >= lo.z && p.x < hi.x && p.y < hi.y && p.z < hi.z;
  }
};

namespace detail {

// Coordinate a of sample k, computed exactly as RayCaster::take_sample computes the position
// (t = t_entry + k·dt, then origin + t·dir): the clip's decision and the sample's value see the same
// float. It is monotone in k (each step is a monotone float operation), so per axis the samples
// inside a slab form one run of indices, found from an estimate by stepping to the exact boundary.
SL_HOST_DEVICE SL_INLINE float sample_coord(const Ray& ray, float t_entry, float dt, int k, int a) {
  const float t = t_entry + float(k) * dt;
  return ray.at(t)[a];
}

// First k in [0, k_end] for which pred(k) holds, pred monotone (false … false true … true), starting
// the search at the estimate `guess`.
template <class Pred>
SL_HOST_DEVICE int first_true(int guess, int k_end, const Pred& pred) {
  int k = guess < 0 ? 0 : (guess > k_end ? k_end : guess);
  if (k < k_end && pred(k)) {
    while (k > 0 && pred(k - 1)) --k;
  } else {
    while (k < k_end && !pred(k)) ++k;
  }
  return k;
}

// Index estimate of where coordinate a crosses plane `x` (only a starting point for first_true).
SL_HOST_DEVICE SL_INLINE int crossing_guess(const Ray& ray, float t_entry, float inv_dt, int k_end, int a, float x) {
  const float k = ((x - ray.origin[a]) / ray.dir[a] - t_entry) * inv_dt;
  if (!(k > 0.0f)) return 0;  // also NaN
  return k < float(k_end) ? int(k) : k_end;
}

}  // namespace detail

// The samples k of [k0, k1) whose positions lie in the clip, narrowed in place (k0 >= k1: none).
// Exact: the union over the regions of a k-d split of the clipped index sets is the unclipped set,
// and the sets are disjoint (tests/core/sample_clip_test.cpp).
SL_HOST_DEVICE inline void clip_samples(const SampleClip& c, const Ray& ray, float t_entry, float dt, float inv_dt,
                                        int& k0, int& k1) {
  if (!c.enabled || k0 >= k1) return;
  for (int a = 0; a < 3 && k0 < k1; ++a) {
    const float d = ray.dir[a];
    const float lo = c.lo[a], hi = c.hi[a];
    if (d == 0.0f) {
      const float x = detail::sample_coord(ray, t_entry, dt, k0, a);  // constant along the ray
      if (!(x >= lo && x < hi)) k1 = k0;
      continue;
    }
    // Along +d the run starts at the first k with x >= lo and ends at the first with x >= hi; along -d
    // it starts at the first with x < hi and ends at the first with x < lo. Infinite faces bound nothing.
    const bool up = d > 0.0f;
    const int end = k1;
    auto first_past = [&](float plane) {
      return detail::first_true(detail::crossing_guess(ray, t_entry, inv_dt, end, a, plane), end, [&](int k) {
        const float x = detail::sample_coord(ray, t_entry, dt, k, a);
        return up ? x >= plane : x < plane;
      });
    };
    const float enter = up ? lo : hi, leave = up ? hi : lo;
    if (enter != (up ? -INFINITY : INFINITY)) {
      const int s = first_past(enter);
      k0 = s > k0 ? s : k0;
    }
    if (leave != (up ? INFINITY : -INFINITY)) {
      const int e = first_past(leave);
      k1 = e < k1 ? e : k1;
    }
  }
  if (k1 < k0) k1 = k0;
}

}  // namespace sl
