// Eight DVR samples at a time on the CPU (AVX2, chosen at run time): positions, clamped voxel
// coordinates, voxel-mask bits, trilinear blends and the transfer function's opacity of grid samples
// k .. k+7 of one ray, lane for lane the same IEEE single-precision operations in the same order as the
// scalar caster (core/recon/sampling.h, core/scene/transfer_function.h; no FMA contraction), so every value is the
// scalar one bit for bit. The caster then composites the lanes in order (core/cast/raycast.h), so the
// image is the same with or without it. Host only: the CUDA kernels run the scalar code, one sample per
// thread step. Where AVX2 is missing (or --simd off) the scalar path runs: that is the fallback.
#pragma once

#include <cstdint>

#include "core/util/math.h"

namespace sl {

// What stays fixed over a march of one ray: the ray, the sample grid, the dense volume (u8 or u16),
// the optional voxel mask (core/occupancy/fine_occupancy.h) and the transfer function's table.
struct DvrBatchArgs {
  const void* data = nullptr;
  int elem_size = 1;           // 1: u8, 2: u16
  ivec3 dims{0};
  vec3 inv_spacing{1.0f};
  vec3 hi{0.0f};               // vec3(dims - 1)
  std::int64_t bytes = 0;      // the volume's size in bytes
  const void* bricks = nullptr;  // the volume's BrickedVolume (core/cast/bricked_volume.h), read instead of `data`
                                 // (the same voxels, fewer cache lines per ray); null: none
  ivec3 brick_counts{0};         // its bricks per axis
  const std::uint64_t* mask_bits = nullptr;  // null: every lane is fetched
  int mask_row_words = 0;      // 64-bit words
  int mask_plane_words = 0;
  // Out of core, a brick's slot (cache/brick_cache.h SlotSampler) as the volume: `data` holds its stored
  // voxels (dims = B + 2 each way), `first` is the level voxel its stored voxel 0 holds, and the lanes'
  // voxels, clamped to `hi` in the level's voxels as the scalar sampler clamps them, index it less `first`
  // (the blend weights are those of the level's voxels). The mask is the slot's, a bit per stored voxel
  // packed x fastest without row padding: bit (z * dims.y + y) * dims.x + x. Off (in core): `first` 0 and
  // the mask's rows padded to words.
  bool slot = false;
  ivec3 first{0};
  // Out of core, the level-adaptive grid (LodParams::grid_level): dvr_mask_scan_spans visits only the
  // positions that are multiples of 2^stride_log2. 0: every position.
  int stride_log2 = 0;
  vec3 origin{0.0f}, dir{0.0f};
  float t_entry = 0.0f, dt = 1.0f;
  const float* tf_table = nullptr;  // vec4 entries, w = opacity
  const float* tf_alpha = nullptr;  // null, or the table's opacities alone (tf_alpha[i] == tf_table[4 * i + 3]):
                                    // a quarter of the bytes the opacity gathers touch
  int tf_size = 0;
  float tf_vmin = 0.0f, tf_inv_step = 0.0f;
};

struct alignas(32) DvrBatchOut {
  float t[8];      // the sample's ray parameter, t_entry + float(k) * dt
  float v[8];      // the trilinear sample
  float alpha[8];  // the transfer function's opacity at v
  float f[8];      // the table coordinate (TransferFunctionView::Coord)
  int i[8];
  unsigned opaque;  // the fetched lanes whose opacity is > 0 (bit j: lane j), the rest being clear
};

// True when this CPU runs the AVX2 path (checked once).
bool sample_batch_available();

// True when a volume of these dims / mask fits the batch's 32-bit offsets (checked once per march).
bool sample_batch_fits(const DvrBatchArgs& a);

// Samples k .. k+n-1 (1 <= n <= 8) of the ray: the bit of lane j is set when sample k+j was fetched
// (its voxel-mask bit is set, or there is no mask) and `out` holds its value and opacity; -1 when a
// lane's voxels reach the volume's last bytes (a 4-byte gather would read past them): the caller
// takes those samples one by one.
int dvr_batch(const DvrBatchArgs& a, int k, int n, DvrBatchOut& out);

// dvr_batch of the n samples ks[0 .. n-1] (any indices; ks holds 8 ints, 1 <= n <= 8) without the
// voxel-mask test: lane j is sample ks[j]. The bits of lanes 0 .. n-1, or -1 as dvr_batch.
int dvr_batch_at(const DvrBatchArgs& a, const int* ks, int n, DvrBatchOut& out);

// A run of grid samples [k0, k1) of one ray. Trivial (no initializers): a ray's array of them is not
// zeroed before it is filled.
struct SampleSpan {
  int k0, k1;
};

// Appends to ks[queued ..] the samples of the ascending spans spans[s .. n) of one ray, from position k
// of spans[s] (the multiples of 2^a.stride_log2 among them), whose voxel-mask bit is set, ascending,
// testing eight positions at a time; the set
// positions of one span and then the next are queued alike, so the spans of a ray share its
// batches (a short span does not end in a batch of its own). Stops once at least `want` are queued
// (s, k: where to go on) or the spans are done (s == n). ks holds want + 8 ints (queued < want).
int dvr_mask_scan_spans(const DvrBatchArgs& a, const SampleSpan* spans, int n, int& s, int& k, int* ks, int queued,
                        int want);

}  // namespace sl
