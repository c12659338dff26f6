// The per-frame ray-casting loop shared by the in-core (dense) and out-of-core (virtual) CPU paths:
// screen tiles in parallel, each pixel walking its method's spans on the global sample grid (Alg. 6
// for segment lists, kd-restart for the octree; the per-pixel walk is core/cast/cast_pixel.h, which the
// CUDA kernels share), and the frame's counters.
#pragma once

#include <algorithm>
#include <atomic>
#include <bit>
#include <cstdint>

#include "core/cast/cast_pixel.h"
#include "core/frame/frame.h"
#include "core/occupancy/octree_skip.h"
#include "core/util/parallel.h"
#include "core/cast/raycast.h"
#include "core/lists/segment_list.h"
#include "core/lists/segment_list_builder.h"

namespace sl {

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

}  // namespace detail

// Casts every pixel of `frame.image` (already sized) and fills the ray-casting part of its stats.
template <class Sampler>
void cast_frame(const RayCaster<Sampler>& caster, const RayGenerator& gen, const Box3& vbox, const SkipInputs& skip,
                Frame& frame) {
  Image& img = frame.image;
  auto& samples_ch = img.channel("samples");
  auto& dc_ch = img.channel("depth_complexity");
  float* depth_ch = nullptr;  // the depth (render_mode.h: writes_depth) per pixel, -1 where there is none
  if (writes_depth(caster.p.mode)) {
    auto& d = img.channel("depth");
    std::fill(d.begin(), d.end(), -1.0f);
    depth_ch = d.data();
  }
  detail::Counters counters;
  Timer timer;
  const BatchPlans<Sampler> plans(caster, &skip.fine);  // once per frame, not per span
  const auto cast_tile = [&](const RayCaster<Sampler>& tc, int x0, int y0, int x1, int y1) {
    std::uint64_t samples = 0, useful = 0, rays = 0, dc_sum = 0;
    std::uint32_t misses = 0, dc_max = 0, dc_min = 0xFFFFFFFFu;
    // pixel_span for the tile's pixels, four at a time: its rays (detail::tile_rays) and their slab
    // tests against the volume box (detail::slab4), both bit for bit gen.ray() and intersect(); a
    // pixel's ray is cast where the lane hits at some t > 0, pixel_span's t_exit > max(t_entry, 0).
    constexpr int T = kTileSize;
    struct alignas(16) TileRays {
      float origin[3][T * T], inv_dir[3][T * T], dir[3][T * T];
    };
    thread_local TileRays tr;
    detail::tile_rays(gen, ScreenRect{x0, y0, x1 - 1, y1 - 1}, tr.origin, tr.inv_dir, tr.dir);
    const float* const o[3] = {tr.origin[0], tr.origin[1], tr.origin[2]};
    const float* const inv[3] = {tr.inv_dir[0], tr.inv_dir[1], tr.inv_dir[2]};
    alignas(16) float t0[4], t1[4];
    for (int y = y0; y < y1; ++y) {
      for (int xg = x0; xg < x1; xg += 4) {  // x0 is a multiple of 4: groups of lanes 0..3
        const int k0 = (y - y0) * T + (xg - x0);
        for (unsigned hit = detail::slab4<ListBuildPath::Fast>(o, inv, std::size_t(k0), vbox, t0, t1); hit != 0u;
             hit &= hit - 1u) {
          const int lane = std::countr_zero(hit), x = xg + lane, k = k0 + lane;
          if (x >= x1) break;  // past the image's edge
          Ray ray;
          ray.origin = vec3(tr.origin[0][k], tr.origin[1][k], tr.origin[2][k]);
          ray.dir = vec3(tr.dir[0][k], tr.dir[1][k], tr.dir[2][k]);
          const float t_entry = t0[lane] > 0.0f ? t0[lane] : 0.0f, t_exit = t1[lane];
          const std::size_t i = std::size_t(y) * img.width + x;
          RayAccum acc = skip.rays != nullptr ? skip.rays[i] : RayAccum{};
          const std::uint32_t dc = detail::cast_pixel(tc, skip, i, ray, t_entry, t_exit, acc, misses, &plans);
          if (skip.rays != nullptr) skip.rays[i] = acc;
          img.rgba[i] = tc.resolve(acc);
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
    }
    counters.samples += samples;
    counters.useful += useful;
    counters.rays += rays;
    counters.misses += misses;
    counters.dc_sum += dc_sum;
    detail::atomic_max(counters.dc_max, dc_max);
    detail::atomic_min(counters.dc_min, dc_min);
  };
  parallel_for_tiles(img.width, img.height, [&](int x0, int y0, int x1, int y1) {
    if constexpr (requires(Sampler& s, std::uint64_t* w) {
                    s.count_tile_into(w);
                    s.add_tile_counts(w);
                  }) {
      // A sampler with counters of its own (out of core: the sample shortfall, cache/virtual_sampler.h)
      // counts the tile on its own copy into the tile's words, added to the frame's once instead of
      // by an atomic add per span.
      std::uint64_t words[Sampler::kTileCountWords] = {};
      RayCaster<Sampler> local = caster;
      local.volume.count_tile_into(words);
      cast_tile(local, x0, y0, x1, y1);
      caster.volume.add_tile_counts(words);
    } else {
      cast_tile(caster, x0, y0, x1, y1);
    }
  });
  frame.stats.time_ms.raycast = timer.ms();
  record_cast_counters(CastCounters::from(counters), skip.method != SkipMethod::None, frame.stats);
}

}  // namespace sl
