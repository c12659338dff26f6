// The per-frame ray-casting loop shared by the in-core (dense) and out-of-core (virtual) CPU paths:
// screen tiles in parallel, each pixel walking its method's spans on the global sample grid (Alg. 6
// for segment lists, kd-restart for the octree), and the frame's counters.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstdint>

#include "core/cpu_renderer.h"
#include "core/octree_skip.h"
#include "core/parallel.h"
#include "core/raycast.h"
#include "core/segment_list.h"

namespace sl {

// What the per-pixel loop needs to know about the skipping structures of this frame.
struct SkipInputs {
  SkipMethod method = SkipMethod::None;
  SegmentListView lists;  // sparseleap, bbox
  SkipOctreeView octree;  // octree
};

namespace detail {

struct Counters {
  std::atomic<std::uint64_t> samples{0}, useful{0}, rays{0}, misses{0}, dc_sum{0};
  std::atomic<std::uint32_t> dc_max{0};
  std::atomic<std::uint32_t> dc_min{0xFFFFFFFFu};
};

template <class T>
void atomic_max(std::atomic<T>& a, T v) {
  T cur = a.load(std::memory_order_relaxed);
  while (v > cur && !a.compare_exchange_weak(cur, v, std::memory_order_relaxed)) {
  }
}
template <class T>
void atomic_min(std::atomic<T>& a, T v) {
  T cur = a.load(std::memory_order_relaxed);
  while (v < cur && !a.compare_exchange_weak(cur, v, std::memory_order_relaxed)) {
  }
}

// One pixel: walks the method's spans on the global sample grid (Alg. 6 for segment lists; kd-restart
// for the octree). Returns the depth complexity: segments of the list, or octree nodes visited.
template <class Sampler>
std::uint32_t cast_pixel(const RayCaster<Sampler>& caster, const SkipInputs& skip, std::size_t pixel,
                         const Ray& ray, float t_entry, float t_exit, RayAccum& acc, std::uint32_t& misses) {
  const int k_end = sample_index(t_exit, t_entry, caster.p.inv_dt);
  switch (skip.method) {
    case SkipMethod::None:
      caster.march(ray, t_entry, 0, k_end, acc);
      return 0;
    case SkipMethod::Octree: {
      std::uint32_t nodes = 0;
      for (float t = t_entry; t < t_exit && !acc.done;) {
        const KdRestartStep st = skip.octree.step(ray, t, t_exit);
        nodes += st.nodes_visited;
        if (st.cls != OccupancyClass::Empty) {
          caster.march_span(ray, t_entry, sample_index(st.t0, t_entry, caster.p.inv_dt),
                            sample_index(st.t1, t_entry, caster.p.inv_dt), k_end, acc);
        }
        t = st.t1;
      }
      return nodes;
    }
    case SkipMethod::BBox:
    case SkipMethod::SparseLeap: {
      const std::uint32_t n = skip.lists.count(pixel);
      const RayEvent* ev = skip.lists.list(pixel);
      const std::uint32_t segments = segment_count(ev, n);
      for (std::uint32_t k = 0; k < segments && !acc.done; ++k) {
        const RaySegment seg = list_segment(ev, n, k, t_exit);
        if (!needs_sampling(seg.cls) || !(seg.t1 > seg.t0)) continue;
        caster.march_span(ray, t_entry, sample_index(seg.t0, t_entry, caster.p.inv_dt),
                          sample_index(seg.t1, t_entry, caster.p.inv_dt), k_end, acc,
                          seg.cls == OccupancyClass::Unknown);
        if (seg.cls == OccupancyClass::Unknown) ++misses;  // occupancy miss (resolved out of core)
      }
      return segments;
    }
  }
  return 0;
}

}  // namespace detail

// Casts every pixel of `frame.image` (already sized) and fills the ray-casting part of its stats.
template <class Sampler>
void cast_frame(const RayCaster<Sampler>& caster, const RayGenerator& gen, const Box3& vbox, const SkipInputs& skip,
                Frame& frame) {
  Image& img = frame.image;
  auto& samples_ch = img.channel("samples");
  auto& dc_ch = img.channel("depth_complexity");
  float* depth_ch = nullptr;  // iso: hit distance t per pixel, -1 where the ray finds no surface
  if (caster.p.mode == RenderMode::Iso) {
    auto& d = img.channel("depth");
    std::fill(d.begin(), d.end(), -1.0f);
    depth_ch = d.data();
  }
  detail::Counters counters;
  Timer timer;
  parallel_for_tiles(img.width, img.height, [&](int x0, int y0, int x1, int y1) {
    std::uint64_t samples = 0, useful = 0, rays = 0, dc_sum = 0;
    std::uint32_t misses = 0, dc_max = 0, dc_min = 0xFFFFFFFFu;
    for (int y = y0; y < y1; ++y) {
      for (int x = x0; x < x1; ++x) {
        const Ray ray = gen.ray(x, y);
        const Interval iv = intersect(ray, vbox);
        const float t_entry = iv.t0 > 0.0f ? iv.t0 : 0.0f;
        if (!(iv.t1 > t_entry)) continue;
        const std::size_t i = std::size_t(y) * img.width + x;
        RayAccum acc;
        const std::uint32_t dc = detail::cast_pixel(caster, skip, i, ray, t_entry, iv.t1, acc, misses);
        img.rgba[i] = caster.resolve(acc);
        samples_ch[i] = float(acc.samples);
        dc_ch[i] = float(dc);
        if (depth_ch) depth_ch[i] = acc.hit_t;
        samples += acc.samples;
        useful += acc.useful_samples;
        dc_sum += dc;
        dc_max = std::max(dc_max, dc);
        dc_min = std::min(dc_min, dc);
        ++rays;
      }
    }
    counters.samples += samples;
    counters.useful += useful;
    counters.rays += rays;
    counters.misses += misses;
    counters.dc_sum += dc_sum;
    detail::atomic_max(counters.dc_max, dc_max);
    detail::atomic_min(counters.dc_min, dc_min);
  });
  Stats& st = frame.stats;
  st.time_ms.raycast = timer.ms();
  st.samples = counters.samples;
  st.useful_samples = counters.useful;
  st.rays = counters.rays;
  st.occupancy_misses = counters.misses;
  if (skip.method != SkipMethod::None && st.rays > 0) {
    st.depth_complexity_avg = double(counters.dc_sum) / double(st.rays);
    st.depth_complexity_max = counters.dc_max;
    st.depth_complexity_min = counters.dc_min.load() == 0xFFFFFFFFu ? 0u : counters.dc_min.load();
  }
}

}  // namespace sl
