// One pixel's ray cast, shared by the CPU frame loop (core/frame/cast_tiles.h) and the CUDA kernels
// (cuda/): the method's spans on the global sample grid — Alg. 6 for segment lists, kd-restart for the
// octree, everything for `none` (DESIGN.md "Ray casting"). SL_HOST_DEVICE and free of std::atomic/std::function,
// so nvcc compiles it unchanged (STYLE.md #2: one copy of each algorithm).
#pragma once

#include <cstddef>
#include <cstdint>

#include "core/scene/camera.h"
#include "core/util/config.h"
#include "core/occupancy/fine_occupancy.h"
#include "core/occupancy/octree_skip.h"
#include "core/cast/raycast.h"
#include "core/scene/render_mode.h"
#include "core/cast/sample_clip.h"
#include "core/lists/segment_list.h"

namespace sl {

// What the per-pixel loop needs to know about the skipping structures of this frame. Plain views:
// host pointers on the CPU, device pointers once uploaded (cuda/).
struct SkipInputs {
  SkipMethod method = SkipMethod::None;
  SegmentListView lists;  // sparseleap, bbox
  SkipOctreeView octree;  // octree
  FineOccupancyView fine; // sparseleap: cells skipped inside sampled segments (empty: off; bbox never sets it)
  SampleClip clip;        // distributed: only the samples in this rank's region (off: all)
  // A depth pass (out of core, a pinned level whose working set does not fit the cache:
  // cache/out_of_core/depth_passes.h; read only with `rays`): only the samples of each ray with t
  // in [pass_t0, pass_t1). The passes of a ray partition its grid samples (sample_index) and exact
  // iso's stretches, so passes cast in order, each from the ray's state the last one left, composite
  // the same samples in the same order as one pass: the same image.
  float pass_t0 = 0.0f, pass_t1 = INFINITY;
  // Per pixel, the ray's state to start from, where the pass leaves its own (host memory: the CPU
  // devices only); null: every ray starts afresh.
  RayAccum* rays = nullptr;
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

// The grid samples [k0, k1) of the ray's stretch [t0, t1), narrowed to the rank's samples [kc0, kc1).
SL_HOST_DEVICE SL_INLINE void span_samples(float t0, float t1, float t_entry, float inv_dt, int kc0, int kc1, int& k0,
                                           int& k1) {
  k0 = sample_index(t0, t_entry, inv_dt);
  k1 = sample_index(t1, t_entry, inv_dt);
  k0 = k0 > kc0 ? k0 : kc0;
  k1 = k1 < kc1 ? k1 : kc1;
}

#if !defined(__CUDA_ARCH__)
// cast_pixel's segment walk (Alg. 6) for a CPU batch that takes a ray's spans together: the sampled
// segments' spans go to `flush(spans, n, finish)` a chunk at a time (false once the ray has
// terminated; `finish`: nothing may stay pending after it); an UNKNOWN segment is marched on its own
// after the chunk before it is finished (its miss counted as cast_pixel counts it).
template <class Sampler, class Flush>
void walk_segment_chunks(const RayCaster<Sampler>& caster, const SkipInputs& skip, const RayEvent* ev,
                         std::uint32_t n, std::uint32_t segments, const Ray& ray, float t_entry, float t_exit, int k_end,
                         int kc0, int kc1, RayAccum& acc, std::uint32_t& misses, const BatchPlans<Sampler>* plans,
                         Flush&& flush) {
  constexpr int kChunk = RayCaster<Sampler>::kSpanChunk;
  SampleSpan spans[kChunk];
  int ns = 0;
  for (std::uint32_t i = 0; i < segments; ++i) {
    const RaySegment seg = list_segment(ev, n, i, t_exit);
    if (!needs_sampling(seg.cls) || !(seg.t1 > seg.t0)) continue;
    int k0, k1;
    span_samples(seg.t0, seg.t1, t_entry, caster.p.inv_dt, kc0, kc1, k0, k1);
    k1 = k1 < k_end ? k1 : k_end;  // march_span's bound
    if (seg.cls == OccupancyClass::Unknown) {
      const bool alive = flush(spans, ns, true);
      ns = 0;
      if (!alive) return;
      if (k0 < k1) caster.march_span(ray, t_entry, k0, k1, k_end, acc, true, &skip.fine, plans);
      ++misses;
      if (acc.done) return;
      continue;
    }
    if (k0 >= k1) continue;
    spans[ns++] = SampleSpan{k0, k1};
    if (ns == kChunk) {
      ns = 0;
      if (!flush(spans, kChunk, false)) return;
    }
  }
  flush(spans, ns, true);
}
#endif

// One pixel: walks the method's spans on the global sample grid (Alg. 6 for segment lists; kd-restart
// for the octree). Returns the depth complexity: segments of the list, or octree nodes visited.
// `misses` counts the UNKNOWN segments sampled (occupancy misses, resolved out of core). `plans`: the
// CPU batch's per-frame inputs for this `skip` (core/cast/raycast_batch.inc; none on the device).
template <class Sampler>
SL_HOST_DEVICE std::uint32_t cast_pixel(const RayCaster<Sampler>& caster, const SkipInputs& skip, std::size_t pixel,
                                        const Ray& ray, float t_entry, float t_exit, RayAccum& acc,
                                        std::uint32_t& misses, const BatchPlans<Sampler>* plans = nullptr) {
  const int k_end = sample_index(t_exit, t_entry, caster.p.inv_dt);
  if (acc.done) return 0;  // ended in an earlier depth pass
  // The rank's samples of the global grid (all of them in a single process); every span is narrowed
  // to them, so the spans still partition the rank's samples exactly (core/cast/sample_clip.h).
  int kc0 = 0, kc1 = k_end;
  clip_samples(skip.clip, ray, t_entry, caster.p.dt, caster.p.inv_dt, kc0, kc1);
  const bool pass = skip.rays != nullptr;  // a depth pass narrows them too
  if (pass) {
    const int a = sample_index(skip.pass_t0, t_entry, caster.p.inv_dt);
    const int b = sample_index(skip.pass_t1, t_entry, caster.p.inv_dt);
    kc0 = a > kc0 ? a : kc0;
    kc1 = b < kc1 ? b : kc1;
  }
  // Exact iso works on stretches of t instead of sample indices: the rank's share of the ray is its
  // stretch inside the region box [t_in, t_out) (the whole ray in a single process). Neighbouring regions
  // share the face, whose crossing both compute from the same plane, so the ranks of a k-d split
  // partition the ray and each root is found by exactly one of them, from cells within a voxel of the
  // region (as the trilinear samples near its faces).
  const bool exact = caster.p.exact_iso();
  float tc0 = t_entry, tc1 = t_exit;
  if (exact && skip.clip.enabled) {
    const Interval iv = intersect(ray, Box3{skip.clip.lo, skip.clip.hi});
    if (iv.t0 > tc0) tc0 = iv.t0;
    if (iv.t1 < tc1) tc1 = iv.t1;
  }
  if (pass && skip.pass_t0 > tc0) tc0 = skip.pass_t0;
  if (pass && skip.pass_t1 < tc1) tc1 = skip.pass_t1;
  const auto span = [&](float t0, float t1, bool unknown, const FineOccupancyView* fine) {
    if (exact) {
      const float a = t0 > tc0 ? t0 : tc0, b = t1 < tc1 ? t1 : tc1;
      if (a < b) caster.march_exact(ray, a, b, acc, unknown);
      return;
    }
    int k0, k1;
    span_samples(t0, t1, t_entry, caster.p.inv_dt, kc0, kc1, k0, k1);
    if (k0 < k1) caster.march_span(ray, t_entry, k0, k1, k_end, acc, unknown, fine, plans);
  };
  switch (skip.method) {
    case SkipMethod::None:
      if (exact) {
        caster.march_exact(ray, tc0, tc1, acc);
      } else {
        caster.march(ray, t_entry, kc0, kc1, acc, false, nullptr, plans);
      }
      return 0;
    case SkipMethod::Octree: {
      std::uint32_t nodes = 0;
      for (float t = t_entry; t < t_exit && !acc.done;) {
        const KdRestartStep st = skip.octree.step(ray, t, t_exit);
        nodes += st.nodes_visited;
        if (st.cls != OccupancyClass::Empty) span(st.t0, st.t1, false, nullptr);
        t = st.t1;
      }
      return nodes;
    }
    case SkipMethod::BBox:
    case SkipMethod::SparseLeap: {
      const std::uint32_t n = skip.lists.count(pixel);
      const RayEvent* ev = skip.lists.list(pixel);
      const std::uint32_t segments = segment_count(ev, n);
#if !defined(__CUDA_ARCH__)
      if constexpr (requires(DvrBatchArgs& b) { caster.volume.slot_batch(b); }) {
        // Out of core on the CPU, a ray's known spans go to the batch together (march_spans): the
        // spans that share a resident brick share one scan of its slot.
        if (!exact && caster.slot_spans_apply(&skip.fine)) {
          walk_segment_chunks(caster, skip, ev, n, segments, ray, t_entry, t_exit, k_end, kc0, kc1, acc, misses, plans,
                              [&](const SampleSpan* spans, int ns, bool) {
                                return ns == 0 || caster.march_spans(ray, t_entry, spans, ns, acc);
                              });
          return segments;
        }
      }
      if constexpr (BatchMarch<Sampler>::kElem > 0) {
        // On the CPU, where the batch scans the voxel mask, the ray's spans share one queue of found
        // samples (BatchMarch::scan_spans): the same samples, taken in fuller batches.
        const BatchPlan* pl = plans != nullptr && !exact && !acc.done ? plans->find(&skip.fine) : nullptr;
        if (pl != nullptr && pl->ok && pl->scan) {
          BatchMarch<Sampler> batch(caster, *pl, ray, t_entry);
          typename BatchMarch<Sampler>::SpanScan q;
          walk_segment_chunks(caster, skip, ev, n, segments, ray, t_entry, t_exit, k_end, kc0, kc1, acc, misses, plans,
                              [&](const SampleSpan* spans, int ns, bool finish) {
                                const bool alive = batch.scan_spans(ray, t_entry, spans, ns, acc, q);
                                return finish ? alive && batch.scan_finish(ray, t_entry, acc, q) : alive;
                              });
          return segments;
        }
      }
#endif
      for (std::uint32_t k = 0; k < segments && !acc.done; ++k) {
        const RaySegment seg = list_segment(ev, n, k, t_exit);
        if (!needs_sampling(seg.cls) || !(seg.t1 > seg.t0)) continue;
        span(seg.t0, seg.t1, seg.cls == OccupancyClass::Unknown, &skip.fine);
        if (seg.cls == OccupancyClass::Unknown) ++misses;  // occupancy miss (resolved out of core)
      }
      return segments;
    }
  }
  return 0;
}

}  // namespace detail
}  // namespace sl
