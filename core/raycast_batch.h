// The CPU's batched march (core/sample_batch.h): RayCaster::march()'s DVR path with the samples taken
// eight at a time and composited lane by lane in order, so the image, the sample counts and the early
// termination are those of the scalar march. Host only: the CUDA kernels compile the scalar march.
// Included by core/raycast.h after RayCaster, whose march() hands a ray to it where it applies.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "core/bricked_volume.h"
#include "core/fine_occupancy.h"
#include "core/raycast.h"
#include "core/sample_batch.h"

#if !defined(__CUDA_ARCH__)

namespace sl {

// The element size of a dense sampler's volume the batch reads: 1 or 2 for u8 / u16 in core, 0 for
// every other sampler (which always samples one by one).
template <class Sampler>
inline constexpr int kBatchElem = 0;
template <class LabT>
inline constexpr int kBatchElem<DenseSampler<std::uint8_t, LabT>> = 1;
template <class LabT>
inline constexpr int kBatchElem<DenseSampler<std::uint16_t, LabT>> = 2;

// What BatchMarch::prepare works out that is the same for every ray of a frame: whether the batch
// applies, its inputs without the ray, the voxel mask it tests and how it finds the mask's set bits.
struct BatchPlan {
  bool ok = false;
  DvrBatchArgs b;                       // BatchMarch adds the ray's origin, direction and t_entry
  const VoxelMaskView* mask = nullptr;  // the voxel mask march_local would test (none: every sample)
  bool scan = false;                    // find the mask's set bits by scanning (else by the cell walk)
};

// One ray's batched march over a caster (a friend of RayCaster: it composites with the caster's own
// take_sample for the samples it does not batch): a plan, completed with the ray.
template <class Sampler>
struct BatchMarch : BatchPlan {
  static constexpr int kElem = kBatchElem<Sampler>;
  // Runs shorter than this are sampled one by one (a batch costs about as much as two scalar samples).
  static constexpr int kMinRun = 2;
  // Under a voxel mask whose set bits fill less than this share of the occupied fine cells, march()
  // scans the mask; at or above it, it walks the cells (see march()). Measured on the bench-peers
  // volumes (2 threads, 512², alternating runs): at fill 0.13 (neurites) the scan is 12-16 % faster, at
  // 0.59 (blobs) and 0.78 (MRI) the walk 5-10 % faster; the crossover lies between.
  static constexpr float kScanFill = 0.4f;

  const RayCaster<Sampler>& c;

  explicit BatchMarch(const RayCaster<Sampler>& caster) : c(caster) {}
  // The batch of `pl` (which must apply: pl.ok) for one ray: begin() without a default plan first.
  BatchMarch(const RayCaster<Sampler>& caster, const BatchPlan& pl, const Ray& ray, float t_entry)
      : BatchPlan(pl), c(caster) {
    b.origin = ray.origin;
    b.dir = ray.dir;
    b.t_entry = t_entry;
  }

  // The batch's inputs for this ray, or false where it does not apply (the scalar march then runs).
  // From `plans` where they hold `fine`'s plan, else worked out here (plan()).
  bool prepare(const Ray& ray, float t_entry, const FineOccupancyView* fine, const BatchPlans<Sampler>* plans) {
    const BatchPlan* known = plans ? plans->find(fine) : nullptr;
    if (known) return begin(*known, ray, t_entry);
    return begin(plan(c, fine), ray, t_entry);
  }

  // The batch for one ray of a plan (false where the plan says it does not apply).
  [[gnu::always_inline]] bool begin(const BatchPlan& pl, const Ray& ray, float t_entry) {
    if (!pl.ok) return false;
    BatchPlan::operator=(pl);
    b.origin = ray.origin;
    b.dir = ray.dir;
    b.t_entry = t_entry;
    return true;
  }

  // Where the batch applies, for every ray of `caster` and `fine`: DVR without lighting, trilinear, one
  // level, a u8/u16 dense volume, a CPU with AVX2, and a voxel mask (if any; none without fine cells or
  // off level 0) on the sampled volume's own voxel grid.
  static BatchPlan plan(const RayCaster<Sampler>& c, const FineOccupancyView* fine) {
    BatchPlan pl;
    const CastParams& p = c.p;
    if (!p.simd || p.mode != RenderMode::Dvr || p.lighting.enabled || p.filter != Filter::Linear ||
        !p.lod.constant() || !sample_batch_available()) {
      return pl;
    }
    const auto& g = c.volume.volume;
    if (g.data == nullptr || p.tf.table == nullptr) return pl;
    DvrBatchArgs& b = pl.b;
    b.data = g.data;
    b.elem_size = kElem;
    b.dims = g.dims;
    b.inv_spacing = g.inv_spacing;
    b.hi = vec3(g.dims - 1);
    b.bytes = std::int64_t(g.dims.x) * g.dims.y * g.dims.z * b.elem_size;
    if (const BrickedVolume* bricks = c.volume.bricks) {
      b.bricks = bricks->data();
      b.brick_counts = bricks->bricks();
    }
    b.dt = p.dt;
    b.tf_table = &p.tf.table[0].x;
    b.tf_size = p.tf.size;
    b.tf_vmin = p.tf.vmin;
    b.tf_inv_step = p.tf.inv_step;
    b.mask_bits = nullptr;
    const VoxelMaskView* mask =
        fine && fine->enabled() && fine->voxels.enabled() && p.lod.level_at(0.0f) == 0 ? &fine->voxels : nullptr;
    if (mask) {
      // The batch tests the mask in the volume's voxel coordinates: a mask on other voxels cannot be.
      if (!(mask->inv_spacing == b.inv_spacing) || !(mask->max_coord == b.hi)) return pl;
      b.mask_bits = mask->bits;
      b.mask_row_words = mask->row_words;
      b.mask_plane_words = mask->plane_words;
      pl.mask = mask;
      pl.scan = mask->fill < kScanFill;
    }
    pl.ok = sample_batch_fits(b);
    return pl;
  }

  // march() of samples [k0, k1) after a successful prepare(); false once the ray has terminated. The
  // samples are march_local's: under a voxel mask those whose mask bit is set (a clear fine cell holds
  // none), else those of the occupied fine cells (or of the whole span without them). They are found
  // in one of two ways. Scan: the mask bit of every position of the span, eight at a time; the set
  // ones are queued and sampled in full batches. Walk: the fine cells, whose occupied runs are sampled
  // in batches of consecutive positions (under the mask, the lanes whose bit is clear stay idle). A
  // sparse mask in its cells (thin neurites) leaves the walk's batches nearly empty, and the scan wins;
  // a dense one (an MRI head) fills them, and the walk, which crosses a clear cell in one step, wins.
  bool march(const Ray& ray, float t_entry, int k0, int k1, RayAccum& acc_out, bool unknown,
             const FineOccupancyView* fine) {
    RayAccum acc = acc_out;  // a local, as RayCaster::march
    SampleContext ctx;
    ctx.occupancy_unknown = unknown;
    ctx.level = c.p.lod.level_at(0.0f);
    float clear_v = NAN;  // as march_local
    bool alive;
    if (scan) {
      // One span through the spans' scan (its context: the dense sampler reads no occupancy_unknown).
      const SampleSpan span{k0, k1};
      SpanScan q;
      alive = scan_spans(ray, t_entry, &span, 1, acc, q) && scan_finish(ray, t_entry, acc, q);
    } else if (fine && fine->enabled() && k0 < k1) {
      FineCellWalk walk(*fine, ray, ray.at(t_entry + float(k0) * c.p.dt));
      alive = walk_cells(ray, t_entry, k0, k1, acc, ctx, clear_v, walk, *fine);
    } else {
      int k = k0;  // no fine cells: no voxel mask either (prepare)
      alive = take_run(ray, t_entry, k, k1, acc, ctx, clear_v);
    }
    acc_out = acc;
    return alive;
  }

  // The pending samples of a ray's spans marched by scan_spans: found, not yet taken.
  // Samples the scan finds before they are taken (in batches of eight): a deep queue sets up the scan
  // once per 64 samples instead of per batch; positions scanned past a ray's termination are the cost.
  static constexpr int kScanAhead = 64;
  struct SpanScan {
    alignas(32) int queue[kScanAhead + 8];  // [0, queued) found (not zeroed: written before read)
    int queued = 0;
    float clear_v = NAN;  // as march_local
  };

  // march() of the ray's ascending spans spans[0 .. n) (in-core DVR, none UNKNOWN) after a prepare()
  // that chose the scan (`scan`): their set mask bits queued alike, so consecutive spans share batches
  // and a short span does not end in a batch of its own; once kScanAhead are found they are taken in
  // batches of eight, and what the spans leave queued stays in `q` for the next call or scan_finish
  // (which takes it all). The same samples in the same order as march() span by span, so
  // the same composite, counts and termination (the lanes after the terminating one are not counted).
  // False once the ray has terminated.
  bool scan_spans(const Ray& ray, float t_entry, const SampleSpan* spans, int n, RayAccum& acc_out, SpanScan& q) {
    RayAccum acc = acc_out;  // a local, as march()
    SampleContext ctx;
    ctx.level = c.p.lod.level_at(0.0f);
    bool alive = true;
    int s = 0, k = n > 0 ? spans[0].k0 : 0;
    while (s < n) {
      q.queued = dvr_mask_scan_spans(b, spans, n, s, k, q.queue, q.queued, kScanAhead);
      if (q.queued < kScanAhead) continue;  // the spans are done: the rest waits for the next ones
      int at = 0;
      for (; q.queued - at >= 8; at += 8) {
        if (!take_queued(ray, t_entry, q.queue + at, 8, acc, ctx, q.clear_v)) {
          alive = false;
          break;
        }
      }
      if (!alive) break;
      q.queued -= at;
      for (int j = 0; j < q.queued; ++j) q.queue[j] = q.queue[at + j];
    }
    acc_out = acc;
    return alive;
  }

  // Takes what scan_spans left queued; false once the ray has terminated.
  bool scan_finish(const Ray& ray, float t_entry, RayAccum& acc_out, SpanScan& q) {
    if (q.queued == 0) return !acc_out.done;
    RayAccum acc = acc_out;
    SampleContext ctx;
    ctx.level = c.p.lod.level_at(0.0f);
    bool alive = true;
    for (int at = 0; at < q.queued && alive; at += 8) {
      alive = take_queued(ray, t_entry, q.queue + at, q.queued - at < 8 ? q.queued - at : 8, acc, ctx, q.clear_v);
    }
    q.queued = 0;
    acc_out = acc;
    return alive;
  }

 private:
  // Samples ks[0 .. n-1] (visible under the mask, ascending) in one batch, composited in order.
  bool take_queued(const Ray& ray, float t_entry, const int* ks, int n, RayAccum& acc, SampleContext& ctx,
                   float& clear_v) const {
    DvrBatchOut o;
    if (dvr_batch_at(b, ks, n, o) < 0) {
      for (int j = 0; j < n; ++j) {
        if (!c.take_sample(ray, t_entry, ks[j], acc, ctx, clear_v, false, mask)) return false;
      }
      return true;
    }
    return composite_lanes(ray, Compositing(c.p), o, (1u << n) - 1u, acc, ctx) < 0;
  }

  // What compositing a lane reads of the caster's parameters, as locals: read through `c`, they could
  // change (as far as the compiler knows) with every store to the accumulator, and are reloaded per lane.
  struct Compositing {
    TransferFunctionView tf;
    bool label_mask, ert;
    float ert_threshold;
    explicit Compositing(const CastParams& p)
        : tf(p.tf), label_mask(p.label_mask), ert(p.ert), ert_threshold(p.ert_threshold) {}
  };

  // The number of lanes set in an 8-bit lane mask, without popcnt (this file is compiled for the
  // baseline target, where __builtin_popcount is a call into libgcc).
  static std::uint32_t lane_count(unsigned m) {
    m = m - ((m >> 1) & 0x55u);
    m = (m & 0x33u) + ((m >> 2) & 0x33u);
    return (m + (m >> 4)) & 0x0Fu;
  }

  // The fetched lanes of a batch (bits of `fetched`) composited in order exactly as take_sample would
  // take them one by one: each counted; a clear one (opacity 0) changes nothing else, so only the
  // opaque ones (o.opaque) go through the label test and the blend. The lane that terminated the ray
  // (the lanes after it are not taken, and not counted), or -1 while it goes on.
  // With SSE2 the accumulator stays in registers over the batch (colour and opacity as one vector,
  // the opacity also as a scalar for the next lane's weight) and is stored once at the end: through
  // memory, each lane's blend waited on the previous lane's store (a store-to-load round trip on the
  // ray's one dependency chain). The operations per lane are composite_over's, in its order; the
  // scalar A + w is the vector's fourth lane A + w * 1 bit for bit (w * 1 == w).
  [[gnu::always_inline]] int composite_lanes(const Ray& ray, const Compositing& cs, const DvrBatchOut& o,
                                             unsigned fetched, RayAccum& acc, SampleContext& ctx) const {
    acc.samples += lane_count(fetched);
#if defined(__SSE2__)
    unsigned bits = o.opaque;
    if (bits == 0u) return -1;
    static_assert(offsetof(RayAccum, alpha) == offsetof(RayAccum, color) + 3 * sizeof(float));
    float* const ca = &acc.color.x;
    __m128 sum = _mm_loadu_ps(ca);  // colour, opacity
    float alpha = acc.alpha, hit_t = acc.hit_t;
    std::uint32_t useful = acc.useful_samples;
    int last = -1;
    for (; bits != 0u; bits &= bits - 1u) {
      const int j = __builtin_ctz(bits);
      const float t = o.t[j];  // t_entry + float(k) * dt, as take_sample's
      if (cs.label_mask && !c.visible_label(ray.at(t), ctx)) continue;
      // composite_over(tf.rgb_at(tc), a, ...): the colour's blend of the two table entries, then
      // color += w * rgb, alpha += w (w * 1 in the fourth lane), four channels wide.
      const float* e = &cs.tf.table[o.i[j]].x;
      const __m128 e0 = _mm_loadu_ps(e), e1 = _mm_loadu_ps(e + 4);
      const __m128 blend = _mm_add_ps(e0, _mm_mul_ps(_mm_set1_ps(o.f[j]), _mm_sub_ps(e1, e0)));
      const __m128 rgb1 = _mm_or_ps(_mm_and_ps(blend, _mm_castsi128_ps(_mm_setr_epi32(-1, -1, -1, 0))),
                                    _mm_setr_ps(0.0f, 0.0f, 0.0f, 1.0f));
      const float w = (1.0f - alpha) * o.alpha[j];
      sum = _mm_add_ps(sum, _mm_mul_ps(_mm_set1_ps(w), rgb1));
      alpha = alpha + w;
      // composited(): the count, the depth, early termination.
      ++useful;
      if (hit_t < 0.0f && alpha >= kDepthOpacity) hit_t = t;
      if (cs.ert && alpha >= cs.ert_threshold) {
        last = j;
        break;
      }
    }
    _mm_storeu_ps(ca, sum);
    acc.hit_t = hit_t;
    acc.useful_samples = useful;
    if (last >= 0) {
      acc.done = true;
      acc.samples -= lane_count(fetched >> (last + 1));
    }
    return last;
#else
    for (unsigned bits = o.opaque; bits != 0u; bits &= bits - 1u) {
      const int j = __builtin_ctz(bits);
      const float t = o.t[j];
      if (cs.label_mask && !c.visible_label(ray.at(t), ctx)) continue;
      const TransferFunctionView::Coord tc{o.i[j], o.f[j]};
      if (!RayCaster<Sampler>::composite_over(cs.tf.rgb_at(tc), o.alpha[j], acc, t, cs.ert, cs.ert_threshold)) {
        acc.samples -= lane_count(fetched >> (j + 1));
        return j;
      }
    }
    return -1;
#endif
  }

  // march_local's fine-cell walk: the samples of consecutive occupied cells are one run (the same
  // samples as the cell-by-cell walk: a cell owns the samples before its exit that the previous cells
  // did not take); then the samples past the grid's edge, if any. Under the mask (if any) throughout.
  bool walk_cells(const Ray& ray, float t_entry, int k, int k1, RayAccum& acc, SampleContext& ctx, float& clear_v,
                  FineCellWalk& walk, const FineOccupancyView& fine) {
    int run_end = k;  // the pending run of occupied cells: [k, run_end)
    for (;;) {
      int next = sample_index(walk.exit(), t_entry, c.p.inv_dt);
      next = next < k1 ? next : k1;
      const bool occupied = fine.occupied_at(walk.index);
      if (occupied && next > run_end) run_end = next;
      const bool last = (occupied ? run_end : next) >= k1 || !walk.advance(fine, ray);
      if ((!occupied || last) && run_end > k) {
        if (!take_run(ray, t_entry, k, run_end, acc, ctx, clear_v, mask)) return false;
      }
      if (!occupied && next > k) k = next;
      if (run_end < k) run_end = k;
      if (last) break;
    }
    return take_run(ray, t_entry, k, k1, acc, ctx, clear_v, mask);
  }

  // Samples [k, end): in batches where the run is long enough, the rest one by one. `m`: the voxel mask
  // b tests (null: every sample is fetched), which the samples taken one by one test too.
  bool take_run(const Ray& ray, float t_entry, int& k, int end, RayAccum& acc, SampleContext& ctx, float& clear_v,
                const VoxelMaskView* m = nullptr) const {
    if (end - k >= kMinRun && !take_batches(ray, t_entry, k, end, acc, ctx, clear_v, m)) return false;
    for (; k < end; ++k) {
      if (!c.take_sample(ray, t_entry, k, acc, ctx, clear_v, false, m)) return false;
    }
    return true;
  }

  // Samples [k, end) in batches of eight, composited lane by lane in order, exactly as take_sample
  // would (the same counts, the same early termination). False once the ray has terminated.
  bool take_batches(const Ray& ray, float t_entry, int& k, int end, RayAccum& acc, SampleContext& ctx, float& clear_v,
                    const VoxelMaskView* m) const {
    const Compositing cs(c.p);
    DvrBatchOut o;
    while (k < end) {
      const int n = end - k < 8 ? end - k : 8;
      const int visible = dvr_batch(b, k, n, o);
      if (visible < 0) {
        // A lane at the volume's last bytes: these samples one by one.
        for (const int stop = k + n; k < stop; ++k) {
          if (!c.take_sample(ray, t_entry, k, acc, ctx, clear_v, false, m)) return false;
        }
        continue;
      }
      const int last = composite_lanes(ray, cs, o, unsigned(visible), acc, ctx);
      if (last >= 0) {
        k += last + 1;
        return false;
      }
      k += n;
    }
    return true;
  }
};

// The batch's plans of one frame (BatchMarch::plan): for the spans without fine cells and for those of
// the frame's fine view, made once by the CPU's tile loop (core/cast_frame.h) instead of once per span.
template <class Sampler>
struct BatchPlans {
  const FineOccupancyView* fine = nullptr;
  BatchPlan none, with_fine;

  std::vector<float> alpha;  // the table's opacities alone, which the batch's gathers read (DvrBatchArgs::tf_alpha)

  BatchPlans(const RayCaster<Sampler>& caster, const FineOccupancyView* f) : fine(f) {
    if constexpr (BatchMarch<Sampler>::kElem > 0) {
      none = BatchMarch<Sampler>::plan(caster, nullptr);
      with_fine = BatchMarch<Sampler>::plan(caster, f);
      if (none.ok || with_fine.ok) {
        const TransferFunctionView& tf = caster.p.tf;
        alpha.resize(std::size_t(tf.size));
        for (int i = 0; i < tf.size; ++i) alpha[std::size_t(i)] = tf.table[i].w;
        none.b.tf_alpha = with_fine.b.tf_alpha = alpha.data();
      }
    }
  }
  BatchPlans(const BatchPlans&) = delete;  // the plans point into `alpha`
  BatchPlans& operator=(const BatchPlans&) = delete;
  // The plan of spans marched with `f`, or null for a fine view these plans were not made for.
  const BatchPlan* find(const FineOccupancyView* f) const { return f == nullptr ? &none : f == fine ? &with_fine : nullptr; }
};

}  // namespace sl

#endif  // !__CUDA_ARCH__
