// Per-ray integration along the global sample grid t_k = t_entry + k * dt (DESIGN.md "Ray casting"). Every
// skipping method calls march() on the index ranges it does not skip, so all methods take the very
// same samples in the same order and produce the same image when culling is conservative.
// Compiled by the CPU backend and, unchanged, by the CUDA kernels (SL_HOST_DEVICE).
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>

#include "core/recon/bspline.h"
#include "core/util/config.h"
#include "core/recon/exact_iso.h"
#include "core/occupancy/fine_occupancy.h"
#include "core/scene/labels.h"
#include "core/util/math.h"
#include "core/util/ray.h"
#include "core/scene/render_mode.h"
#include "core/recon/sampling.h"
#include "core/cast/sample_batch.h"
#include "core/cast/shading.h"
#include "core/scene/transfer_function.h"

namespace sl {

// Level of detail per sample (DESIGN.md "Virtual memory"): the coarsest level whose voxel footprint is no larger than
// the pixel footprint times a bias. One level (in-core data) or a pinned level makes it constant.
struct LodParams {
  int levels = 1;              // levels available (1: level 0 only)
  int pinned = -1;             // >= 0: always this level
  float pixel_angle = 0.0f;    // perspective: footprint = t * pixel_angle (world units)
  float pixel_size = 0.0f;     // orthographic: footprint = pixel_size
  float inv_voxel = 1.0f;      // 1 / level-0 voxel size (min spacing) times the bias
  // Level-adaptive sample grid: the level the grid's step is made for (out of core, the frame's
  // finest). A sample at a coarser level l is taken only at every 2^(l - grid_level)-th grid index
  // and stands for all of them (its opacity is corrected for the longer step), so a far level is
  // sampled about as densely as its voxels, not as densely as the nearest level's. The rule depends
  // on the grid index and the level alone, so every method takes the same samples. -1: every grid
  // sample at every level.
  int grid_level = -1;

  // One level for every sample (pinned, or a single level): the caster sets it once per span.
  SL_HOST_DEVICE SL_INLINE bool constant() const { return pinned >= 0 || levels <= 1; }
  SL_HOST_DEVICE SL_INLINE int level_at(float t) const {
    if (pinned >= 0) return pinned;
    if (levels <= 1) return 0;
    const float ratio = (pixel_size > 0.0f ? pixel_size : t * pixel_angle) * inv_voxel;
    if (!(ratio >= 2.0f)) return 0;
    const int l = floor_log2(ratio);
    return l < levels - 1 ? l : levels - 1;
  }
  // floorf(log2f(x)) for x >= 2, from the exponent's bits: a log2f within a few ulps of exact rounds
  // to the exponent e alike unless x lies within 2^-16 of 2^e or 2^(e+1), where log2f itself answers
  // (so the level is that of log2f everywhere). level_at runs per sample, where a log2f call would
  // cost about as much as the sample.
  SL_HOST_DEVICE SL_INLINE static int floor_log2(float x) {
#if defined(__CUDA_ARCH__)
    const std::uint32_t bits = __float_as_uint(x);
#else
    std::uint32_t bits;
    std::memcpy(&bits, &x, sizeof bits);
#endif
    const int e = int((bits >> 23) & 0xFFu) - 127;
    if (e == 128) return e;  // an infinity (never a NaN: level_at asks x >= 2): above every level
    const std::uint32_t mantissa = bits & 0x7FFFFFu;
    if (mantissa < 0x80u || mantissa >= 0x7FFF80u) return int(floorf(log2f(x)));
    return e;
  }
  // log2 of the grid steps one sample at `level` stands for.
  SL_HOST_DEVICE SL_INLINE int stride_log2(int level) const {
    return grid_level >= 0 && level > grid_level ? level - grid_level : 0;
  }
};

// Where a sample is taken: its level of detail and whether its occupancy is still unknown (the
// out-of-core sampler then reports its brick as a miss even when the data are resident; §8.2).
struct SampleContext {
  int level = 0;
  bool occupancy_unknown = false;
};

// The in-core sampler: dense intensity and optional labels at one level.
class BrickedVolume;

template <class VolT, class LabT>
struct DenseSampler {
  DenseGrid<VolT> volume;
  DenseGrid<LabT> labels;  // labels.data == nullptr: no label volume
  // Host: `volume` copied into bricks (core/cast/bricked_volume.h), which the CPU's batched DVR reads instead
  // of the dense rows (the same voxels); null: none. The scalar and device code never read it.
  const BrickedVolume* bricks = nullptr;

  SL_HOST_DEVICE SL_INLINE float sample(const vec3& p, const SampleContext&) const { return volume.sample(p); }
  // From the clamped voxel coordinate the voxel mask computed (its volume is this one; take_sample).
  SL_HOST_DEVICE SL_INLINE float sample_coord(const vec3& u, const SampleContext&) const {
    return volume.sample_coord(u);
  }
  // Voxel v (clamped) of the one level: exact iso's cell corners without a trilinear blend.
  SL_HOST_DEVICE SL_INLINE float voxel(const ivec3& v, const SampleContext&) const { return volume.voxel_clamped(v); }
  SL_HOST_DEVICE SL_INLINE std::uint32_t label_at(const vec3& p, const SampleContext&) const {
    return labels.data ? labels.label_at(p) : 0u;
  }
  SL_HOST_DEVICE vec3 gradient(const vec3& p, const vec3& spacing, const SampleContext&) const {
    return volume.gradient(p, spacing);
  }
};

struct CastParams {
  RenderMode mode = RenderMode::Dvr;
  float dt = 0.5f;         // world distance between samples = step * min(spacing)
  float inv_dt = 2.0f;
  float iso = 0.5f;
  IsoMethod iso_method = IsoMethod::Exact;
  Filter filter = Filter::Linear;  // reconstruction (core/recon/bspline.h): trilinear or a B-spline
  bool ert = false;        // early ray termination at A >= ert_threshold
  float ert_threshold = 0.99f;
  bool label_mask = false; // a sample contributes only where its label is enabled
  bool simd = true;        // CPU: DVR samples eight at a time where AVX2 runs (core/cast/sample_batch.h); same image
  bool leaps = true;       // out of core: march_leaping's leaps; same image and counts (off: the tests' reference)
  vec3 spacing{1.0f};
  TransferFunctionView tf; // opacity already corrected for dt (DESIGN.md "Ray casting")
  Lighting lighting;       // dvr, labels: Blinn–Phong on the gradient (core/cast/shading.h) when enabled
  LabelSetView labels;
  LodParams lod;

  // Iso mode by exact per-cell roots (march_exact on the ray's stretches) instead of grid samples.
  SL_HOST_DEVICE SL_INLINE bool exact_iso() const { return mode == RenderMode::Iso && iso_method == IsoMethod::Exact; }
  // Whether the level-adaptive grid (LodParams::grid_level) thins the samples. Sampled iso brackets
  // crossings between consecutive grid samples and keeps every one.
  SL_HOST_DEVICE SL_INLINE bool strided() const {
    return lod.grid_level >= 0 && !lod.constant() && mode != RenderMode::Iso;
  }
};

// Accumulated state of one ray (front-to-back, premultiplied).
// Level-of-detail changes one exact-iso walk follows along a ray (LodParams levels; brick.h's maximum).
inline constexpr int kMaxLodPasses = 16;

struct RayAccum {
  vec3 color{0.0f};
  float alpha = 0.0f;
  float mip_max = 0.0f;
  float hit_t = -1.0f;  // depth (render_mode.h): iso, t of the surface hit; DVR, labels: t where alpha reaches 0.5
  std::uint32_t samples = 0;         // samples taken
  std::uint32_t useful_samples = 0;  // samples that contributed (opacity > 0)
  int prev_k = -2;                   // index of the previous sample taken (iso bracketing)
  float prev_v = 0.0f;
  bool mip_any = false;
  bool done = false;                 // terminated (ERT or iso hit): later spans are not sampled
};

// Index of the first grid sample at or after t (clamped at 0). Every method converts its span
// boundaries with this one function, so adjacent spans partition the grid exactly.
SL_HOST_DEVICE inline int sample_index(float t, float t_entry, float inv_dt) {
  const float x = (t - t_entry) * inv_dt;
  if (!(x > 0.0f)) return 0;
  if (x > 2.0e9f) return 2000000000;
  // ceil by truncation (x > 0): ceilf is a libm call on baseline x86-64 (no SSE4.1 roundss).
  const int i = int(x);
  return float(i) < x ? i + 1 : i;
}

// Blinn–Phong with a headlight (light along the view ray), two-sided.
SL_HOST_DEVICE inline vec3 shade_headlight(const vec3& base, const vec3& gradient, const vec3& view_dir) {
  const float len = glm::length(gradient);
  if (!(len > 0.0f)) return 0.3f * base;
  vec3 n = gradient / len;
  if (glm::dot(n, view_dir) > 0.0f) n = -n;  // face the viewer
  const float diffuse = glm::max(0.0f, -glm::dot(n, view_dir));
  const float specular = powf(diffuse, 32.0f);  // half vector == light == -view_dir for a headlight
  return base * (0.25f + 0.75f * diffuse) + vec3(0.3f * specular);
}

#if !defined(__CUDA_ARCH__)
template <class Sampler>
struct BatchMarch;  // core/cast/raycast_batch.inc: the CPU's batched DVR march
#endif
// core/cast/raycast_batch.inc: what the batched march needs of a frame, made once by the CPU's tile loop (the
// device code passes none).
template <class Sampler>
struct BatchPlans;

// Per-ray integration over a sampler (DenseSampler in core; the out-of-core sampler reads through the
// page table and brick cache). The sampler is a template parameter: no virtual call per sample.
template <class Sampler>
struct RayCaster {
  CastParams p;
  Sampler volume;
#if !defined(__CUDA_ARCH__)
  friend struct BatchMarch<Sampler>;  // takes the samples it does not batch with take_sample
#endif

  SL_HOST_DEVICE SL_INLINE bool visible_label(const vec3& pos, const SampleContext& c) const {
    return !p.label_mask || p.labels.enabled(volume.label_at(pos, c));
  }

  // The reconstruction at pos (CastParams::filter): the sampler's trilinear sample, or the B-spline
  // from 8 of them (core/recon/bspline.h) on the voxels of the sample's level.
  SL_HOST_DEVICE SL_INLINE float value_at(const vec3& pos, const SampleContext& c) const {
    if (p.filter == Filter::Linear) return volume.sample(pos, c);
    return filtered(pos, c);
  }

  // The gradient of that reconstruction: the sampler's central difference of the trilinear samples,
  // or the central difference of the B-spline, one voxel of the level apart.
  SL_HOST_DEVICE vec3 gradient_at(const vec3& pos, const SampleContext& c) const {
    if (p.filter == Filter::Linear) return volume.gradient(pos, p.spacing, c);
    return filtered_gradient(pos, c);
  }

  // The gradient of label `id`'s mask (1 on its voxels, 0 elsewhere, trilinearly interpolated between
  // voxel centres) at pos: the normal of the label's surface, smooth rather than staircased (lit
  // labels mode). Central differences one voxel of the level apart.
  SL_HOST_DEVICE SL_DEVICE_NOINLINE vec3 label_gradient(const vec3& pos, std::uint32_t id, const SampleContext& c) const {
    const vec3 h = level_voxel(c);
    vec3 g;
    SL_DEVICE_NO_UNROLL
    for (int a = 0; a < 3; ++a) {
      vec3 d(0.0f);
      d[a] = h[a];
      g[a] = (label_mask(pos + d, id, h, c) - label_mask(pos - d, id, h, c)) / (2.0f * h[a]);
    }
    return g;
  }

 private:
  SL_HOST_DEVICE SL_INLINE vec3 level_voxel(const SampleContext& c) const { return p.spacing * float(1 << c.level); }

  SL_HOST_DEVICE SL_DEVICE_NOINLINE float filtered(const vec3& pos, const SampleContext& c) const {
    return bspline_sample(p.filter, pos, level_voxel(c), [&](const vec3& q) { return volume.sample(q, c); });
  }

  // The B-spline's central-difference gradient, one voxel of the level apart (the order of
  // central_difference_gradient: +h then -h per axis).
  SL_HOST_DEVICE SL_DEVICE_NOINLINE vec3 filtered_gradient(const vec3& pos, const SampleContext& c) const {
    const vec3 h = level_voxel(c);
    vec3 g;
    SL_DEVICE_NO_UNROLL
    for (int a = 0; a < 3; ++a) {
      vec3 d(0.0f);
      d[a] = h[a];
      g[a] = (filtered(pos + d, c) - filtered(pos - d, c)) / (2.0f * h[a]);
    }
    return g;
  }

  SL_HOST_DEVICE float label_mask(const vec3& q, std::uint32_t id, const vec3& h, const SampleContext& c) const {
    const vec3 u = q / h - 0.5f;
    const vec3 fl(floorf(u.x), floorf(u.y), floorf(u.z));
    const vec3 f = u - fl;
    float m[8];
    SL_DEVICE_NO_UNROLL
    for (int i = 0; i < 8; ++i) {
      const vec3 centre = (fl + vec3(float(i & 1), float((i >> 1) & 1), float((i >> 2) & 1)) + 0.5f) * h;
      m[i] = volume.label_at(centre, c) == id ? 1.0f : 0.0f;  // the sampler clamps to the volume
    }
    const float x00 = m[0] + f.x * (m[1] - m[0]), x10 = m[2] + f.x * (m[3] - m[2]);
    const float x01 = m[4] + f.x * (m[5] - m[4]), x11 = m[6] + f.x * (m[7] - m[6]);
    const float y0 = x00 + f.y * (x10 - x00), y1 = x01 + f.y * (x11 - x01);
    return y0 + f.z * (y1 - y0);
  }

 public:

  // Samples k in [k0, k1). Returns false once the ray has terminated. `unknown`: the span's occupancy
  // is UNKNOWN (an occupancy miss for the out-of-core sampler). `fine` (optional): leave out the
  // samples that fall in its clear cells (exact: they contribute nothing; core/occupancy/fine_occupancy.h).
  // `plans` (CPU, optional): the batched march's per-frame inputs, else it works them out per call.
  SL_HOST_DEVICE bool march(const Ray& ray, float t_entry, int k0, int k1, RayAccum& acc, bool unknown = false,
                            const FineOccupancyView* fine = nullptr,
                            const BatchPlans<Sampler>* plans = nullptr) const {
    if (acc.done) return false;
#if !defined(__CUDA_ARCH__)
    if constexpr (BatchMarch<Sampler>::kElem > 0) {
      // On the CPU, DVR samples eight at a time where the batch applies (core/cast/sample_batch.h): every
      // value it hands back is the scalar one, and the lanes composite in order.
      BatchMarch<Sampler> batch(*this);
      if (batch.prepare(ray, t_entry, fine, plans)) return batch.march(ray, t_entry, k0, k1, acc, unknown, fine);
    }
#else
    (void)plans;
#endif
    // The loop works on local copies (of the caster too): through references the compiler must
    // assume a store to the accumulator may change the sampler's or the table's fields and reloads
    // them every sample; locals whose address never escapes stay in registers.
    RayAccum a = acc;
    const Ray r = ray;
    const RayCaster self = *this;
    // Iso needs every consecutive sample pair of a span to bracket crossings: no cell skipping there.
    const bool alive = fine && fine->enabled() && self.p.mode != RenderMode::Iso
                           ? self.template march_local<true>(r, t_entry, k0, k1, a, unknown, *fine)
                           : self.template march_local<false>(r, t_entry, k0, k1, a, unknown, FineOccupancyView{});
    // The samples the out-of-core sampler's voxel masks left out on this copy's cursor, whichever
    // loop took them.
    if constexpr (requires { self.volume.count_left_out(std::uint64_t(0)); }) self.volume.count_left_out(0);
    acc = a;
    return alive;
  }

 private:
  template <bool kFine>
  SL_HOST_DEVICE SL_INLINE bool march_local(const Ray& ray, float t_entry, int k0, int k1, RayAccum& acc,
                                            bool unknown, const FineOccupancyView fine) const {
    SampleContext ctx;
    ctx.occupancy_unknown = unknown;
    if (p.mode == RenderMode::Iso && k0 > 0 && acc.prev_k != k0 - 1 && k0 < k1) {
      // Prime the bracket with the sample before the span, so a crossing right at a span's start
      // is found exactly as a method without skipping finds it.
      const float t = t_entry + float(k0 - 1) * p.dt;
      ctx.level = p.lod.level_at(t);
      acc.prev_v = value_at(ray.at(t), ctx);
      acc.prev_k = k0 - 1;
      ++acc.samples;
    }
    // The last value whose opacity was zero: runs of equal values (background, uniform regions) skip
    // the table. The opacity is a function of the value alone, so this changes nothing but the cost.
    float clear_v = NAN;  // compares unequal to every value
    const bool lod_varies = !p.lod.constant();
    if (!lod_varies) ctx.level = p.lod.level_at(0.0f);
    int k = k0;
    // The per-sample bit of the voxel mask (core/occupancy/fine_occupancy.h), where it was built for these
    // inputs: a sample whose trilinear cell cannot contribute is not fetched. A clear fine cell holds
    // no set bit, so the samples taken are exactly those whose bit is set, which the CPU's batched
    // march finds with or without walking the cells (core/cast/raycast_batch.inc).
    const VoxelMaskView* mask = nullptr;
    if constexpr (kFine) {
      mask = fine.voxels.enabled() && !lod_varies && ctx.level == 0 && p.filter == Filter::Linear &&
                     (p.mode == RenderMode::Dvr || p.mode == RenderMode::Labels)
                 ? &fine.voxels
                 : nullptr;
      // Cell by cell: the grid samples of a clear cell are skipped, those of an occupied cell taken.
      // A cell owns the samples before its exit that the previous cells did not take; rounding can
      // leave it none, or hand a sample to its neighbour — within the half-voxel margin either way.
      if (k < k1) {
        FineCellWalk walk(fine, ray, ray.at(t_entry + float(k) * p.dt));
        for (;;) {
          int next = sample_index(walk.exit(), t_entry, p.inv_dt);
          next = next < k1 ? next : k1;
          if (fine.occupied_at(walk.index)) {
            for (; k < next; ++k) {
              if (!take_sample(ray, t_entry, k, acc, ctx, clear_v, lod_varies, mask)) return false;
            }
          } else if (next > k) {
            k = next;
          }
          if (k >= k1 || !walk.advance(fine, ray)) break;
        }
      }
    }
    if constexpr (!kFine && requires { volume.fine_cell(ray, vec3(0.0f), vec3(0.0f), ctx, clear_v, clear_v); }) {
      if (p.leaps && p.filter == Filter::Linear && (p.mode == RenderMode::Dvr || p.mode == RenderMode::Labels)) {
        return march_leaping(ray, t_entry, k, k1, acc, ctx, clear_v, lod_varies);
      }
    }
    // Without the grid every sample; with it the samples past the grid's edge, if rounding left any
    // (still under the mask). The level-adaptive grid visits only the indices it takes.
    if (p.strided()) {
      for (k = taken_from(k, t_entry); k < k1; k = taken_from(k + 1, t_entry)) {
        if (!take_sample(ray, t_entry, k, acc, ctx, clear_v, lod_varies, mask)) return false;
      }
      return true;
    }
    for (; k < k1; ++k) {
      if (!take_sample(ray, t_entry, k, acc, ctx, clear_v, lod_varies, mask)) return false;
    }
    return true;
  }

  // The first grid index at or after k (>= 0) that the level-adaptive grid takes: a multiple of its
  // level's stride. The level does not decrease along the ray and strides are powers of two, so an
  // index skipped for one stride is skipped for every later, larger one.
  SL_HOST_DEVICE SL_INLINE int taken_from(int k, float t_entry) const {
    for (;;) {
      const int m = (1 << p.lod.stride_log2(p.lod.level_at(t_entry + float(k) * p.dt))) - 1;
      if ((k & m) == 0) return k;
      k = (k | m) + 1;
    }
  }

  // Opacity of a sample standing for 2^s grid steps: 1 - (1 - a)^(2^s), by s squarings (a itself
  // for one step: 1 - (1 - a) need not round back to a).
  SL_HOST_DEVICE SL_INLINE static float stretched_opacity(float a, int s) {
    if (s == 0) return a;
    float clear = 1.0f - a;
    for (int i = 0; i < s; ++i) clear *= clear;
    return 1.0f - clear;
  }

  // Out of core: the samples [k, k1) with leaps (VirtualSampler::fine_cell) over the clear fine cells
  // of resident bricks (the samples would each find their mask bit clear: left out) and over the
  // stretches where nothing is resident and the one value served there is clear (taken samples
  // that contribute nothing: counted, not fetched). A leap never crosses a change of the level of
  // detail (the level grows along the ray, so the first and last samples of the leap share it only if
  // all between do) nor, for what is served, a brick; so the image and every miss, usage and
  // shortfall count are those of sampling one by one.
  SL_HOST_DEVICE bool march_leaping(const Ray& ray, float t_entry, int k, int k1, RayAccum& acc, SampleContext& ctx,
                                    float& clear_v, bool lod_varies) const {
    const vec3 inv_dir = FineOccupancyView::inverse_direction(ray);
    float occupied_until = -1.0f;  // the samples before this t lie in an occupied cell: no question
    std::uint64_t leapt = 0;
    bool alive = true;
    const bool strided = p.strided();
#if !defined(__CUDA_ARCH__)
    // On the CPU, DVR's samples in a resident brick are found and taken eight at a time from its slot
    // (slot_run): the samples, values, composite and counts of the one-by-one walk.
    bool batch = false;
    int slot_fits = -1;  // whether the slots fit the batch (they all have one size): -1 not asked yet
    if constexpr (requires(DvrBatchArgs& b) { volume.slot_batch(b); }) {
      batch = p.simd && p.mode == RenderMode::Dvr && !p.lighting.enabled && p.tf.table != nullptr &&
              sample_batch_available();
    }
#endif
    if (strided && k < k1) k = taken_from(k, t_entry);
    for (; k < k1; k = strided ? taken_from(k + 1, t_entry) : k + 1) {
      const float t = t_entry + float(k) * p.dt;
      if (t >= occupied_until) {
        if (lod_varies) ctx.level = p.lod.level_at(t);
#if !defined(__CUDA_ARCH__)
        if constexpr (requires(DvrBatchArgs& b) { volume.slot_batch(b); }) {
          // In a resident brick (where fine_cell would answer kClear or kOccupied) the scan of its
          // mask crosses clear cells about as fast as the leaps: the cell itself is not needed.
          if (batch && volume.resident_cells(ray.at(t), ctx)) {
            int stop = k;
            const int r = slot_run(ray, inv_dir, t_entry, k, k1, acc, ctx, clear_v, lod_varies, stop, leapt, slot_fits);
            if (r > 0) {  // [k, stop) taken: on from stop, asking its cell afresh
              k = stop - 1;
              continue;
            }
            if (r < 0) {
              alive = false;
              break;
            }
          }
        }
#endif
        float t_exit, uniform = 0.0f;
        const auto cell = volume.fine_cell(ray, inv_dir, ray.at(t), ctx, t_exit, uniform);
        if (cell == Sampler::kOccupied) {
          occupied_until = t_exit;
        } else if (cell == Sampler::kClear || (cell == Sampler::kUniform && clear_value(uniform, clear_v))) {
          int next = sample_index(t_exit, t_entry, p.inv_dt);
          next = next < k1 ? next : k1;
          // The samples the leap passes: on the level-adaptive grid, the stride's multiples (k is one).
          const int s = strided ? p.lod.stride_log2(ctx.level) : 0;
          if (next > k + 1) {
            int last = k + (((next - k - 1) >> s) << s);
            if (last > k && !volume.in_cursor(ray.at(t_entry + float(last) * p.dt))) {
              next = last;  // rounding put the last one in the next brick: it is not passed over
              last -= 1 << s;
            }
          }
          if (next > k + 1 && (!lod_varies || p.lod.level_at(t_entry + float(next - 1) * p.dt) == ctx.level)) {
            const std::uint64_t n = std::uint64_t(((next - k) + (1 << s) - 1) >> s);
            volume.count_run(ray, t_entry, p.dt, k, next, s, ctx);
            if (cell == Sampler::kClear) {
              leapt += n;
            } else {
              acc.samples += std::uint32_t(n);
            }
            k = next - 1;
            continue;
          }
        }
      }
      if (!take_sample(ray, t_entry, k, acc, ctx, clear_v, lod_varies, nullptr)) {
        alive = false;
        break;
      }
    }
    volume.count_left_out(leapt);
    return alive;
  }

#if !defined(__CUDA_ARCH__)
  // march_leaping's samples from k (in a fine cell of the cursor's brick, served by a resident slot with
  // its voxel mask: its own or a resident ancestor's) to the brick's exit, where brick_spans finds the
  // slot run applies: those whose mask bit is set found and taken eight at a time from the slot, the
  // rest left out, the shortfall counted as sample() would (take_slot_spans).
  // 1: taken, the ray goes on from `stop`; -1: it terminated (`stop`: one past its last sample);
  // 0: the batch does not apply here (nothing done). `fits`: whether the slots fit the batch (-1: ask).
  int slot_run(const Ray& ray, const vec3& inv_dir, float t_entry, int k, int k1, RayAccum& acc, SampleContext& ctx,
               float& clear_v, bool lod_varies, int& stop, std::uint64_t& leapt, int& fits) const {
    BatchMarch<Sampler> run = slot_batch_for(ray, t_entry);
    const SampleSpan span{k, k1};
    SampleSpan sub[1];
    if (brick_spans(ray, inv_dir, t_entry, &span, 1, 0, k, ctx, lod_varies, run.b, fits, sub) == 0) return 0;
    return take_slot_spans(run, ray, t_entry, sub, 1, acc, ctx, clear_v, stop, leapt) ? 1 : -1;
  }

  // The batch of a ray's slot runs: the frame's table and the ray; brick_spans sets the slot.
  BatchMarch<Sampler> slot_batch_for(const Ray& ray, float t_entry) const {
    BatchMarch<Sampler> run(*this);
    DvrBatchArgs& b = run.b;
    b.dt = p.dt;
    b.tf_table = &p.tf.table[0].x;
    b.tf_size = p.tf.size;
    b.tf_vmin = p.tf.vmin;
    b.tf_inv_step = p.tf.inv_step;
    b.origin = ray.origin;
    b.dir = ray.dir;
    b.t_entry = t_entry;
    run.ok = true;
    return run;
  }

  // The spans sub[0 .. m) of one slot (brick_spans) through `run`: every position visited (up to the
  // terminating sample) was taken or left out, as the one-by-one walk counts them, and the shortfall
  // is count_run's. False once the ray has terminated (`stop`: one past its last sample).
  bool take_slot_spans(const BatchMarch<Sampler>& run, const Ray& ray, float t_entry, const SampleSpan* sub, int m,
                       RayAccum& acc, SampleContext& ctx, float& clear_v, int& stop, std::uint64_t& leapt) const {
    std::uint32_t taken = 0;
    const bool alive = run.march_slot_spans(ray, t_entry, sub, m, acc, ctx, clear_v, stop, taken);
    // The positions visited: on the level-adaptive grid, the stride's multiples.
    const int st = run.b.stride_log2, round = (1 << st) - 1;
    std::uint64_t visited = 0;
    for (int j = 0; j < m && sub[j].k0 < stop; ++j) {
      const int a = (sub[j].k0 + round) & ~round;
      const int e = sub[j].k1 < stop ? sub[j].k1 : stop;
      if (e <= a) continue;
      visited += std::uint64_t(((e - a) + round) >> st);
      volume.count_run(ray, t_entry, p.dt, a, e, st, ctx);
    }
    leapt += visited - taken;
    return alive;
  }
#endif

#if !defined(__CUDA_ARCH__)
 public:
  // The spans a ray hands to the CPU batch at once, at most (core/cast/cast_pixel.h: walk_segment_chunks).
  static constexpr int kSpanChunk = 32;

  // Whether march() of a known span would take march_leaping's batched slot runs (out of core on the
  // CPU: DVR through the eight-sample batch, trilinear, leaps on, no fine view), so that march_spans
  // may take a ray's known spans together.
  bool slot_spans_apply(const FineOccupancyView* fine) const {
    if constexpr (requires(DvrBatchArgs& b) { volume.slot_batch(b); }) {
      return !(fine != nullptr && fine->enabled()) && p.leaps && p.filter == Filter::Linear &&
             p.mode == RenderMode::Dvr && p.simd && !p.lighting.enabled && p.tf.table != nullptr &&
             sample_batch_available();
    } else {
      (void)fine;
      return false;
    }
  }

  // march() of a ray's ascending known spans spans[0 .. n) (n <= kSpanChunk, each within the ray's
  // samples), where slot_spans_apply: on one copy of the caster for them all, and where consecutive
  // spans lie in one resident brick, one scan of its slot's mask for them together
  // (BatchMarch::march_slot_spans) instead of a run set-up per span. The same samples in the same
  // order, so the same image and counts. False once the ray has terminated.
  bool march_spans(const Ray& ray, float t_entry, const SampleSpan* spans, int n, RayAccum& acc) const {
    if (acc.done) return false;
    RayAccum a = acc;  // locals, as march()
    const Ray r = ray;
    const RayCaster self = *this;
    const bool alive = self.march_spans_local(r, t_entry, spans, n, a);
    self.volume.count_left_out(0);
    acc = a;
    return alive;
  }

 private:
  bool march_spans_local(const Ray& ray, float t_entry, const SampleSpan* spans, int n, RayAccum& acc) const {
    const vec3 inv_dir = FineOccupancyView::inverse_direction(ray);
    const bool lod_varies = !p.lod.constant();
    SampleContext ctx;
    if (!lod_varies) ctx.level = p.lod.level_at(0.0f);
    float clear_v = NAN;  // as march_local
    std::uint64_t leapt = 0;
    BatchMarch<Sampler> run = slot_batch_for(ray, t_entry);
    int fits = -1;
    SampleSpan sub[kSpanChunk];
    bool alive = true;
    int s = 0, k = n > 0 ? spans[0].k0 : 0;
    while (s < n) {
      const int k1 = spans[s].k1;
      if (k >= k1) {
        if (++s < n) k = spans[s].k0;
        continue;
      }
      const int m = brick_spans(ray, inv_dir, t_entry, spans, n, s, k, ctx, lod_varies, run.b, fits, sub);
      if (m == 0) {
        // The rest of this span as march() takes it (its own slot runs where they apply).
        if (!march_leaping(ray, t_entry, k, k1, acc, ctx, clear_v, lod_varies)) {
          alive = false;
          break;
        }
        if (++s < n) k = spans[s].k0;
        continue;
      }
      int stop = k;
      alive = take_slot_spans(run, ray, t_entry, sub, m, acc, ctx, clear_v, stop, leapt);
      if (!alive) break;
      s += m - 1;  // on from the end of the last one: within its span, or at the next
      k = sub[m - 1].k1;
    }
    volume.count_left_out(leapt);
    return alive;
  }

  // The spans from sample k of spans[s] on that lie in the brick the cursor finds at k, clipped to its
  // exit, into `sub` (their number), where slot_run's conditions hold there: resident with its cells
  // and mask, one level throughout (clipped where the level changes; so one stride of the
  // level-adaptive grid: b.stride_log2), a slot the batch reads (`b` then holds it); 0 where they do not. Samples k .. e - 1 all lie in the brick when k and e - 1 do (a ray's voxel
  // coordinates are monotonic in t), gaps between spans included.
  int brick_spans(const Ray& ray, const vec3& inv_dir, float t_entry, const SampleSpan* spans, int n, int s, int k,
                  SampleContext& ctx, bool lod_varies, DvrBatchArgs& b, int& fits, SampleSpan* sub) const {
    const float t = t_entry + float(k) * p.dt;
    if (lod_varies) ctx.level = p.lod.level_at(t);
    if (!volume.resident_cells(ray.at(t), ctx)) return 0;
    int e = sample_index(volume.cursor_exit(ray, inv_dir), t_entry, p.inv_dt);
    e = e < spans[n - 1].k1 ? e : spans[n - 1].k1;
    while (e > k + 1 && !volume.in_cursor(ray.at(t_entry + float(e - 1) * p.dt))) --e;
    if (lod_varies && e > k + 1 && p.lod.level_at(t_entry + float(e - 1) * p.dt) != ctx.level) {
      // The level changes inside the brick: up to its first position at the next level (the level
      // does not decrease along the ray), where the next call goes on at that level's brick.
      int lo = k + 1, hi = e - 1;  // level(k) is ctx.level; level(hi) is not
      while (lo < hi) {
        const int mid = lo + (hi - lo) / 2;
        if (p.lod.level_at(t_entry + float(mid) * p.dt) == ctx.level) {
          lo = mid + 1;
        } else {
          hi = mid;
        }
      }
      e = lo;
    }
    int m = 0;
    for (int j = s; j < n; ++j) {
      const int a = j == s ? k : spans[j].k0;
      if (a >= e) break;
      sub[m++] = SampleSpan{a, spans[j].k1 < e ? spans[j].k1 : e};
    }
    if (m == 0 || (m == 1 && sub[0].k1 - sub[0].k0 < BatchMarch<Sampler>::kMinRun)) return 0;
    if (lod_varies && p.lod.level_at(t_entry + float(sub[m - 1].k1 - 1) * p.dt) != ctx.level) return 0;
    if (!volume.slot_batch(b)) return 0;
    if (fits < 0) fits = sample_batch_fits(b) ? 1 : 0;
    // On the level-adaptive grid, the level's stride: one level throughout, so one stride.
    b.stride_log2 = p.strided() ? p.lod.stride_log2(ctx.level) : 0;
    return fits != 0 ? m : 0;
  }
#endif

  // Whether a sample of value v composites nothing (DVR, labels: zero opacity), as take_sample
  // decides it; DVR remembers it as its last clear value.
  SL_HOST_DEVICE SL_INLINE bool clear_value(float v, float& clear_v) const {
    if (p.mode == RenderMode::Dvr && v == clear_v) return true;
    if (p.tf.alpha_at(p.tf.coord(v)) > 0.0f) return false;
    if (p.mode == RenderMode::Dvr) clear_v = v;
    return true;
  }

  // Sample k of march_local: fetch, classify, composite. False once the ray has terminated. `mask`
  // (optional): the sample is left out, not fetched, where its trilinear cell's bit is clear (exact:
  // it would composite nothing).
  SL_HOST_DEVICE SL_INLINE bool take_sample(const Ray& ray, float t_entry, int k, RayAccum& acc, SampleContext& ctx,
                                            float& clear_v, bool lod_varies, const VoxelMaskView* mask) const {
    const float t = t_entry + float(k) * p.dt;
    const vec3 pos = ray.at(t);
    float v;
    if (mask) {
      // The mask's coordinate is the sampler's (the in-core renderer builds the mask from the
      // sampled volume, and mask only at level 0): a dense sampler blends from it directly.
      const vec3 u = mask->coord(pos);
      if (!mask->visible_coord(u)) return true;
      if constexpr (requires { volume.sample_coord(u, ctx); }) {
        v = volume.sample_coord(u, ctx);
      } else {
        v = value_at(pos, ctx);
      }
    } else {
      if (lod_varies) {
        ctx.level = p.lod.level_at(t);
        // Off the level-adaptive grid: not a sample (the march loops do not visit such indices).
        if (p.strided() && (k & ((1 << p.lod.stride_log2(ctx.level)) - 1)) != 0) return true;
      }
      if constexpr (requires { volume.sample_unless_clear(pos, ctx, v); }) {
        // Out of core, the serving brick's own voxel mask (cache/brick_cache.h), for trilinear samples in
        // the modes it is built for (the caller's view holds masks only then): left out, not fetched.
        if (p.filter != Filter::Linear) {
          v = value_at(pos, ctx);
        } else if (!volume.sample_unless_clear(pos, ctx, v)) {
          return true;
        }
      } else {
        v = value_at(pos, ctx);
      }
    }
    ++acc.samples;
    switch (p.mode) {
      // Opacity first: the label fetch and the colour are read only for samples that can
      // contribute (the order of the tests does not change which samples composite).
      case RenderMode::Dvr: {
        if (v == clear_v) break;
        const TransferFunctionView::Coord tc = p.tf.coord(v);
        float a = p.tf.alpha_at(tc);
        if (!(a > 0.0f)) {
          clear_v = v;
          break;
        }
        if (lod_varies && p.strided()) a = stretched_opacity(a, p.lod.stride_log2(ctx.level));
        if (!visible_label(pos, ctx)) break;
        vec3 rgb = p.tf.rgb_at(tc);
        if (p.lighting.enabled) rgb = blinn_phong(rgb, gradient_at(pos, ctx), ray.dir, p.lighting);
        if (!composite(rgb, a, acc, t)) return false;
        break;
      }
      case RenderMode::Labels: {
        float a = p.tf.alpha_at(p.tf.coord(v));
        if (!(a > 0.0f)) break;
        if (lod_varies && p.strided()) a = stretched_opacity(a, p.lod.stride_log2(ctx.level));
        const std::uint32_t id = volume.label_at(pos, ctx);
        if (id == 0u || !p.labels.enabled(id)) break;
        vec3 rgb = label_color(id);
        if (p.lighting.enabled) rgb = blinn_phong(rgb, label_gradient(pos, id, ctx), ray.dir, p.lighting);
        if (!composite(rgb, a, acc, t)) return false;
        break;
      }
      case RenderMode::Mip: {
        if (!visible_label(pos, ctx)) break;
        if (!acc.mip_any || v > acc.mip_max) acc.mip_max = v;
        acc.mip_any = true;
        ++acc.useful_samples;
        break;
      }
      case RenderMode::Iso: {
        if (acc.prev_k == k - 1 && ((acc.prev_v < p.iso) != (v < p.iso))) {
          if (iso_hit(ray, t - p.dt, acc.prev_v, t, v, ctx, acc)) return false;
        }
        acc.prev_v = v;
        acc.prev_k = k;
        break;
      }
    }
    return true;
  }

 public:
  // Front-to-back "over" of one premultiplied contribution at ray parameter t (DESIGN.md "Ray casting"), which is
  // the depth once the opacity first reaches kDepthOpacity; false once early ray termination ends the
  // ray.
  SL_HOST_DEVICE SL_INLINE bool composite(const vec3& rgb, float a, RayAccum& acc, float t) const {
    return composite_over(rgb, a, acc, t, p.ert, p.ert_threshold);
  }
  // composite() with the early-termination settings passed in (the CPU batch holds them in registers).
  SL_HOST_DEVICE SL_INLINE static bool composite_over(const vec3& rgb, float a, RayAccum& acc, float t, bool ert,
                                                      float ert_threshold) {
    const float w = (1.0f - acc.alpha) * a;
    acc.color += w * rgb;
    acc.alpha += w;
    return composited(acc, t, ert, ert_threshold);
  }
  // What follows the "over" of a contribution at t: counted, the depth, early ray termination.
  SL_HOST_DEVICE SL_INLINE static bool composited(RayAccum& acc, float t, bool ert, float ert_threshold) {
    ++acc.useful_samples;
    if (acc.hit_t < 0.0f && acc.alpha >= kDepthOpacity) acc.hit_t = t;
    if (ert && acc.alpha >= ert_threshold) {
      acc.done = true;
      return false;
    }
    return true;
  }

  // Samples the span [k0, k1) of a skipping method. Iso mode also takes the sample at k1 (when
  // k1 < k_end): a crossing between a span's last sample and the first skipped one is found exactly as
  // a method without skipping finds it (march() already primes with the sample before k0).
  SL_HOST_DEVICE bool march_span(const Ray& ray, float t_entry, int k0, int k1, int k_end, RayAccum& acc,
                                 bool unknown = false, const FineOccupancyView* fine = nullptr,
                                 const BatchPlans<Sampler>* plans = nullptr) const {
    if (k1 > k_end) k1 = k_end;
    if (p.mode == RenderMode::Iso && k1 < k_end && k0 < k1) ++k1;
    return march(ray, t_entry, k0, k1, acc, unknown, fine, plans);
  }

  // Exact iso (core/recon/exact_iso.h) on the ray's stretch [ta, tb): walks the voxel-centre cells the ray
  // crosses, skips those whose corners all lie on one side of the iso value, and takes the first root of
  // the cubic ray polynomial of the others by LR81. Returns false once the ray has hit (terminated).
  // Roots are accepted in [ta, tb) only, so consecutive stretches of a ray (a method's spans, a rank's
  // share) find each root exactly once; a root is computed from its whole cell, whatever the stretch.
  SL_HOST_DEVICE bool march_exact(const Ray& ray, float ta, float tb, RayAccum& acc, bool unknown = false) const {
    if (acc.done) return false;
    if (!(tb > ta)) return true;
    RayAccum a = acc;  // locals, as march()
    const Ray r = ray;
    const RayCaster self = *this;
    bool alive;
    if (self.p.filter == Filter::Linear) {
      alive = self.march_exact_local(r, ta, tb, a, unknown);
    } else if (self.p.filter == Filter::Quadratic) {
      alive = self.template march_exact_bspline<2>(r, ta, tb, a, unknown);
    } else {
      alive = self.template march_exact_bspline<3>(r, ta, tb, a, unknown);
    }
    acc = a;
    return alive;
  }

 private:
  // The value minus the iso value at the centre of voxel v of the sampled level (voxel size h); the
  // sampler clamps at the faces, which makes the border cells' corners repeat the edge voxels. A
  // sampler with a direct voxel read (in core) is read directly: the same value, no blend.
  SL_HOST_DEVICE SL_INLINE float corner(const ivec3& v, const vec3& h, const SampleContext& ctx) const {
    if constexpr (requires { volume.voxel(v, ctx); }) {
      return volume.voxel(v, ctx) - p.iso;
    } else {
      return volume.sample((vec3(v) + 0.5f) * h, ctx) - p.iso;
    }
  }

  SL_HOST_DEVICE bool march_exact_local(const Ray& ray, float ta, float tb, RayAccum& acc, bool unknown) const {
    SampleContext ctx;
    ctx.occupancy_unknown = unknown;
    const bool lod_varies = !p.lod.constant();
    float t = ta;
    // One pass per level of detail along the ray (one pass in core or with a pinned level).
    for (int pass = 0; pass < 2 * kMaxLodPasses && t < tb; ++pass) {
      ctx.level = p.lod.level_at(t);
      const vec3 h = p.spacing * float(1 << ctx.level);
      const vec3 inv_h = 1.0f / h;
      // Root tolerance: 1e-6 of the cell edge.
      const float tol = 1e-6f * fminf(h.x, fminf(h.y, h.z));
      CellWalk walk(ray, inv_h, t);
      CellCorners c;
      for (int i = 0; i < 8; ++i) c.v[i] = corner(walk.cell + ivec3(i & 1, (i >> 1) & 1, (i >> 2) & 1), h, ctx);
      acc.samples += 8;
      // Bounded for the device: a ray crosses at most |Δu|_1 + 3 cells.
      const float span_cells = (fabsf(walk.ud.x) + fabsf(walk.ud.y) + fabsf(walk.ud.z)) * (tb - t);
      const int max_cells = span_cells < 1.0e8f ? int(span_cells) + 8 : 100000008;
      bool relevel = false;
      for (int n = 0;; ++n) {
        if (walk.t1 > walk.t0 && c.may_cross() && cell_hit(ray, walk, c, t, tb, inv_h, tol, ctx, acc)) return false;
        if (!(walk.t1 < tb) || n >= max_cells) break;
        const int axis = walk.axis, bit = 1 << axis;
        const bool up = walk.step > 0;
        walk.advance();
        if (lod_varies && p.lod.level_at(walk.t0) != ctx.level) {
          t = walk.t0;  // the walk restarts on the new level's cells
          relevel = true;
          break;
        }
        // The four corners on the shared face carry over; the other four are fetched.
        for (int i = 0; i < 8; ++i) {
          if (((i & bit) != 0) == up) continue;  // i: a corner on the face left behind
          c.v[i] = c.v[i ^ bit];
        }
        for (int i = 0; i < 8; ++i) {
          if (((i & bit) != 0) != up) continue;  // i: a corner on the new far face
          c.v[i] = corner(walk.cell + ivec3(i & 1, (i >> 1) & 1, (i >> 2) & 1), h, ctx);
        }
        acc.samples += 4;
      }
      if (!relevel) break;
    }
    return true;
  }

  // march_exact_local for the B-spline of degree D (2: tri-quadratic, 3: tri-cubic): the same walk
  // over the filter's pieces (CellWalk with the filter's grid offset), the (D+1)^3 control points of a
  // piece minus the iso value (those on the faces shared with the next piece carry over), the piece
  // skipped when they all lie on one side, else the first root of its degree-3D ray polynomial.
  template <int D>
  SL_HOST_DEVICE SL_DEVICE_NOINLINE bool march_exact_bspline(const Ray& ray, float ta, float tb, RayAccum& acc, bool unknown) const {
    constexpr int n = D + 1;
    SampleContext ctx;
    ctx.occupancy_unknown = unknown;
    const bool lod_varies = !p.lod.constant();
    float t = ta;
    for (int pass = 0; pass < 2 * kMaxLodPasses && t < tb; ++pass) {
      ctx.level = p.lod.level_at(t);
      const vec3 h = p.spacing * float(1 << ctx.level);
      const vec3 inv_h = 1.0f / h;
      const float tol = 1e-6f * fminf(h.x, fminf(h.y, h.z));
      CellWalk walk(ray, inv_h, t, bspline_grid_offset<D>());
      CellControl<D> c;
      const int first = bspline_first<D>();
      SL_DEVICE_NO_UNROLL
      for (int idx = 0; idx < CellControl<D>::kCount; ++idx) {
        const int i = idx % n, j = (idx / n) % n, k = idx / (n * n);
        c.v[idx] = corner(walk.cell + ivec3(i + first, j + first, k + first), h, ctx);
      }
      acc.samples += CellControl<D>::kCount;
      const float span_cells = (fabsf(walk.ud.x) + fabsf(walk.ud.y) + fabsf(walk.ud.z)) * (tb - t);
      const int max_cells = span_cells < 1.0e8f ? int(span_cells) + 8 : 100000008;
      bool relevel = false;
      for (int cells = 0;; ++cells) {
        if (walk.t1 > walk.t0 && c.may_cross() && bspline_cell_hit<D>(ray, walk, c, t, tb, inv_h, tol, ctx, acc)) {
          return false;
        }
        if (!(walk.t1 < tb) || cells >= max_cells) break;
        const int axis = walk.axis;
        const bool up = walk.step > 0;
        walk.advance();
        if (lod_varies && p.lod.level_at(walk.t0) != ctx.level) {
          t = walk.t0;
          relevel = true;
          break;
        }
        // Shift the control points one place along the axis; fetch the new far face.
        const int stride = axis == 0 ? 1 : (axis == 1 ? n : n * n);
        SL_DEVICE_NO_UNROLL
        for (int idx = up ? 0 : CellControl<D>::kCount - 1; up ? idx < CellControl<D>::kCount : idx >= 0; idx += up ? 1 : -1) {
          const int a = (idx / stride) % n;  // the control point's coordinate along the axis
          if (up ? a < D : a > 0) {
            c.v[idx] = c.v[up ? idx + stride : idx - stride];
          } else {
            const int i = idx % n, j = (idx / n) % n, k = idx / (n * n);
            c.v[idx] = corner(walk.cell + ivec3(i + first, j + first, k + first), h, ctx);
          }
        }
        acc.samples += n * n;
      }
      if (!relevel) break;
    }
    return true;
  }

  template <int D>
  SL_HOST_DEVICE SL_DEVICE_NOINLINE bool bspline_cell_hit(const Ray& ray, const CellWalk& walk, const CellControl<D>& c,
                                                           float t_lo, float tb, const vec3& inv_h, float tol,
                                                           const SampleContext& ctx, RayAccum& acc) const {
    float b[3 * D + 1];
    bspline_ray_bernstein<D>(c, walk.local(walk.t0), walk.local(walk.t1), b);
    return first_shown_root(ray, walk, b, t_lo, tb, tol, ctx, acc, [&](const vec3& f) {
      vec3 g;
      bspline_local<D>(c, f, &g);
      return g * inv_h;
    });
  }

  // The first root in [t_lo, tb) of the cell's ray polynomial whose label is shown: shades it and ends
  // the ray (true), or false when the cell has none.
  SL_HOST_DEVICE bool cell_hit(const Ray& ray, const CellWalk& walk, const CellCorners& c, float t_lo, float tb,
                               const vec3& inv_h, float tol, const SampleContext& ctx, RayAccum& acc) const {
    float b[4];
    ray_bernstein(c, walk.local(walk.t0), walk.local(walk.t1), b);
    return first_shown_root(ray, walk, b, t_lo, tb, tol, ctx, acc,
                            [&](const vec3& f) { return trilinear_gradient_local(c, f) * inv_h; });
  }

  // The first root in [t_lo, tb) of the ray polynomial b (Bernstein form on the cell's stretch of the
  // walk) whose label is shown, by LR81: shades it with `gradient(local point)` (world units) and ends
  // the ray (true), or false when the stretch has none. Roots before t_lo (another stretch's) and
  // masked-out ones are passed over, as the sampled method passes over them.
  template <int N, class Gradient>
  SL_HOST_DEVICE SL_INLINE bool first_shown_root(const Ray& ray, const CellWalk& walk, const float (&b)[N], float t_lo,
                                                 float tb, float tol, const SampleContext& ctx, RayAccum& acc,
                                                 const Gradient& gradient) const {
    const float len = walk.t1 - walk.t0;
    const float tol_s = tol / len;
    float s_from = 0.0f;
    for (int attempt = 0; attempt < 8; ++attempt) {
      float s = 0.0f;
      if (!lr81_first_root(b, s_from, tol_s, s)) return false;
      const float th = walk.t0 + s * len;
      if (!(th < tb)) return false;  // also NaN (a NaN voxel)
      // Past the root by twice the tolerance: the next search cannot find it again.
      const float s_next = s + 2.0f * tol_s;
      if (th < t_lo) {
        const float s_lo = (t_lo - walk.t0) / len;
        s_from = s_next > s_lo ? s_next : s_lo;
        continue;
      }
      const vec3 hit = ray.at(th);
      if (!visible_label(hit, ctx)) {
        s_from = s_next;  // masked out: the ray goes on, as the sampled method's does
        continue;
      }
      acc.color = shade_headlight(vec3(p.tf.lookup(p.iso)), gradient(walk.local(th)), ray.dir);
      acc.alpha = 1.0f;
      acc.hit_t = th;
      acc.done = true;
      ++acc.useful_samples;
      return true;
    }
    return false;
  }

 public:
  // Refines a bracketed crossing by bisection, then shades it; false if its label is masked out.
  SL_HOST_DEVICE bool iso_hit(const Ray& ray, float ta, float va, float tb, float vb, const SampleContext& ctx,
                              RayAccum& acc) const {
    const bool a_below = va < p.iso;
    for (int i = 0; i < 12; ++i) {
      const float tm = 0.5f * (ta + tb);
      const float vm = value_at(ray.at(tm), ctx);
      if ((vm < p.iso) == a_below) {
        ta = tm;
        va = vm;
      } else {
        tb = tm;
        vb = vm;
      }
    }
    const float f = vb != va ? (p.iso - va) / (vb - va) : 0.5f;
    // Clamped so a NaN f (a NaN voxel in the bracket) becomes 0: the hit stays inside the volume.
    const float th = ta + (f > 0.0f ? (f < 1.0f ? f : 1.0f) : 0.0f) * (tb - ta);
    const vec3 hit = ray.at(th);
    if (!visible_label(hit, ctx)) return false;
    const vec3 base = vec3(p.tf.lookup(p.iso));
    acc.color = shade_headlight(base, gradient_at(hit, ctx), ray.dir);
    acc.alpha = 1.0f;
    acc.hit_t = th;
    acc.done = true;
    ++acc.useful_samples;
    return true;
  }

  // Final premultiplied RGBA of the ray.
  SL_HOST_DEVICE vec4 resolve(const RayAccum& acc) const {
    if (p.mode == RenderMode::Mip) {
      if (!acc.mip_any) return vec4(0.0f);
      return vec4(vec3(p.tf.lookup(acc.mip_max)), 1.0f);
    }
    return vec4(acc.color, acc.alpha);
  }
};

}  // namespace sl

// The CPU's batched march, which march() hands DVR rays to (host only).
#include "core/cast/raycast_batch.inc"
