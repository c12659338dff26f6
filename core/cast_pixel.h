// One pixel's ray cast, shared by the CPU frame loop (core/cast_frame.h) and the CUDA kernels
// (cuda/): the method's spans on the global sample grid — Alg. 6 for segment lists, kd-restart for the
// octree, everything for `none` (DESIGN.md §8). SL_HOST_DEVICE and free of std::atomic/std::function,
// so nvcc compiles it unchanged (STYLE.md #2: one copy of each algorithm).
#pragma once

#include <cstddef>
#include <cstdint>

#include "core/camera.h"
#include "core/config.h"
#include "core/fine_occupancy.h"
#include "core/octree_skip.h"
#include "core/raycast.h"
#include "core/render_mode.h"
#include "core/segment_list.h"

namespace sl {

// What the per-pixel loop needs to know about the skipping structures of this frame. Plain views:
// host pointers on the CPU, device pointers once uploaded (cuda/).
struct SkipInputs {
  SkipMethod method = SkipMethod::None;
  SegmentListView lists;  // sparseleap, bbox
  SkipOctreeView octree;  // octree
  FineOccupancyView fine; // sparseleap: cells skipped inside sampled segments (empty: off; bbox never sets it)
};

// The pixel's ray and its span inside the volume box; false when the ray misses the box (nothing to
// cast: the pixel stays transparent and is not counted as a ray).
SL_HOST_DEVICE inline bool pixel_span(const RayGenerator& gen, const Box3& vbox, int x, int y, Ray& ray,
                                      float& t_entry, float& t_exit) {
  ray = gen.ray(x, y);
  const Interval iv = intersect(ray, vbox);
  t_entry = iv.t0 > 0.0f ? iv.t0 : 0.0f;
  t_exit = iv.t1;
  return iv.t1 > t_entry;
}

namespace detail {

// One pixel: walks the method's spans on the global sample grid (Alg. 6 for segment lists; kd-restart
// for the octree). Returns the depth complexity: segments of the list, or octree nodes visited.
// `misses` counts the UNKNOWN segments sampled (occupancy misses, resolved out of core).
template <class Sampler>
SL_HOST_DEVICE std::uint32_t cast_pixel(const RayCaster<Sampler>& caster, const SkipInputs& skip, std::size_t pixel,
                                        const Ray& ray, float t_entry, float t_exit, RayAccum& acc,
                                        std::uint32_t& misses) {
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
                          seg.cls == OccupancyClass::Unknown, &skip.fine);
        if (seg.cls == OccupancyClass::Unknown) ++misses;  // occupancy miss (resolved out of core)
      }
      return segments;
    }
  }
  return 0;
}

}  // namespace detail
}  // namespace sl
