// The ray-casting kernels: one thread per pixel running detail::cast_pixel (core/cast/cast_pixel.h), the
// very function the CPU frame loop runs, over any sampler. One kernel per method family, so the
// method switch folds away and cuobjdump lists a kernel per method (tests/cuda/kernels_test.cpp):
//   sl_cast_none           no skipping
//   sl_cast_octree         kd-restart over the min/max octree (SkipOctreeView::step)
//   sl_cast_segment_lists  Alg. 6 over the per-pixel segment lists (sparseleap and bbox)
// Counters are reduced per warp, then one atomic per warp. Also the per-frame device buffers every
// caster uses: its inputs (FrameInputs) and its outputs (DeviceFrame).
#pragma once

#include <cuda_runtime.h>

#include <cstdint>
#include <vector>

#include "core/cast/cast_pixel.h"
#include "core/frame/frame.h"
#include "core/occupancy/octree_skip.h"
#include "core/frame/stats.h"
#include "cuda/cuda_util.h"

namespace sl::cuda {

struct DeviceCounters {
  unsigned long long samples = 0, useful = 0, rays = 0, misses = 0, dc_sum = 0;
  unsigned int dc_max = 0, dc_min = 0xFFFFFFFFu;
};

struct FrameOutputs {
  vec4* rgba = nullptr;
  float* samples = nullptr;
  float* dc = nullptr;     // depth complexity
  float* depth = nullptr;  // render_mode.h's depth (not MIP), -1 where there is none
  DeviceCounters* counters = nullptr;
};

__device__ inline unsigned long long warp_sum(unsigned long long v) {
  for (int o = 16; o > 0; o >>= 1) v += __shfl_down_sync(0xFFFFFFFFu, v, o);
  return v;
}
__device__ inline unsigned int warp_max(unsigned int v) {
  for (int o = 16; o > 0; o >>= 1) v = max(v, __shfl_down_sync(0xFFFFFFFFu, v, o));
  return v;
}
__device__ inline unsigned int warp_min(unsigned int v) {
  for (int o = 16; o > 0; o >>= 1) v = min(v, __shfl_down_sync(0xFFFFFFFFu, v, o));
  return v;
}

// Every thread of the block reaches the warp reductions (no early return): blocks are 16 x 8.
template <class Sampler>
__device__ void cast_thread(const RayCaster<Sampler>& caster, const RayGenerator& gen, const Box3& vbox,
                            const SkipInputs& skip, const FrameOutputs& out) {
  const int x = int(blockIdx.x * blockDim.x + threadIdx.x);
  const int y = int(blockIdx.y * blockDim.y + threadIdx.y);
  std::uint32_t samples = 0, useful = 0, misses = 0, dc = 0, ray_cast = 0;
  if (x < gen.width && y < gen.height) {
    const std::size_t i = std::size_t(y) * std::size_t(gen.width) + std::size_t(x);
    Ray ray;
    float t_entry, t_exit;
    vec4 rgba(0.0f);
    float hit_t = -1.0f;
    if (pixel_span(gen, vbox, x, y, ray, t_entry, t_exit)) {
      RayAccum acc;
      dc = detail::cast_pixel(caster, skip, i, ray, t_entry, t_exit, acc, misses);
      rgba = caster.resolve(acc);
      samples = acc.samples;
      useful = acc.useful_samples;
      hit_t = acc.hit_t;
      ray_cast = 1;
    }
    out.rgba[i] = rgba;
    out.samples[i] = float(samples);
    out.dc[i] = float(dc);
    if (out.depth) out.depth[i] = hit_t;
  }
  const unsigned long long s = warp_sum(samples), u = warp_sum(useful), r = warp_sum(ray_cast),
                           m = warp_sum(misses), d = warp_sum(dc);
  const unsigned int dmax = warp_max(ray_cast ? dc : 0u), dmin = warp_min(ray_cast ? dc : 0xFFFFFFFFu);
  const unsigned int lane = (threadIdx.y * blockDim.x + threadIdx.x) & 31u;
  if (lane == 0 && r > 0) {
    DeviceCounters* c = out.counters;
    atomicAdd(&c->samples, s);
    atomicAdd(&c->useful, u);
    atomicAdd(&c->rays, r);
    atomicAdd(&c->misses, m);
    atomicAdd(&c->dc_sum, d);
    atomicMax(&c->dc_max, dmax);
    atomicMin(&c->dc_min, dmin);
  }
}

template <class Sampler>
__global__ void __launch_bounds__(128) sl_cast_none(RayCaster<Sampler> caster, RayGenerator gen, Box3 vbox,
                                                    SkipInputs skip, FrameOutputs out) {
  skip.method = SkipMethod::None;
  cast_thread(caster, gen, vbox, skip, out);
}

template <class Sampler>
__global__ void __launch_bounds__(128) sl_cast_octree(RayCaster<Sampler> caster, RayGenerator gen, Box3 vbox,
                                                      SkipInputs skip, FrameOutputs out) {
  skip.method = SkipMethod::Octree;
  cast_thread(caster, gen, vbox, skip, out);
}

template <class Sampler>
__global__ void __launch_bounds__(128) sl_cast_segment_lists(RayCaster<Sampler> caster, RayGenerator gen, Box3 vbox,
                                                             SkipInputs skip, FrameOutputs out) {
  skip.method = SkipMethod::SparseLeap;  // bbox lists are walked the same way
  cast_thread(caster, gen, vbox, skip, out);
}

// Per-frame output buffers on the device and their way back into a Frame.
class DeviceFrame {
 public:
  FrameOutputs prepare(int width, int height, bool depth, cudaStream_t stream) {
    const std::size_t n = std::size_t(width) * std::size_t(height);
    rgba_.reserve(n);
    samples_.reserve(n);
    dc_.reserve(n);
    if (depth) depth_.reserve(n);
    counters_.reserve(1);
    const DeviceCounters zero;
    counters_.upload(&zero, 1, stream);
    return FrameOutputs{rgba_.get(), samples_.get(), dc_.get(), depth ? depth_.get() : nullptr, counters_.get()};
  }
  // Copies the image and counters into `frame` (image sized already) and fills its ray-casting
  // stats as cast_frame does. Synchronises the stream.
  void finish(Frame& frame, SkipMethod method, bool depth, cudaStream_t stream) {
    Image& img = frame.image;
    const std::size_t n = std::size_t(img.width) * std::size_t(img.height);
    rgba_.download(img.rgba.data(), n, stream);
    samples_.download(img.channel("samples").data(), n, stream);
    dc_.download(img.channel("depth_complexity").data(), n, stream);
    if (depth) depth_.download(img.channel("depth").data(), n, stream);
    DeviceCounters d;
    counters_.download(&d, 1, stream);
    check(cudaStreamSynchronize(stream), "ray casting");
    record_cast_counters(CastCounters::from(d), method != SkipMethod::None, frame.stats);
  }

 private:
  DeviceBuffer<vec4> rgba_;
  DeviceBuffer<float> samples_, dc_, depth_;
  DeviceBuffer<DeviceCounters> counters_;
};

// The per-frame inputs of a cast, uploaded here for the in-core and the out-of-core caster alike: the
// transfer-function table, the enabled-label bits and the skipping structures (segment lists; the
// octree in core), into buffers kept between frames.
class FrameInputs {
 public:
  // Uploads what `p` and `skip` point to and repoints them at the device copies.
  void upload(CastParams& p, SkipInputs& skip, cudaStream_t stream) {
    tf_.upload(p.tf.table, std::size_t(p.tf.size), stream);
    p.tf.table = tf_.get();
    if (p.labels.bits) {
      bits_.upload(p.labels.bits, (p.labels.size + 31) / 32, stream);
      p.labels.bits = bits_.get();
    }
    if (skip.method == SkipMethod::SparseLeap || skip.method == SkipMethod::BBox) {
      // The compact lists as they are: the events of all pixels, and per pixel an offset and a count.
      const SegmentListView& v = skip.lists;
      const std::size_t pixels = std::size_t(v.width) * std::size_t(v.height);
      events_.upload(v.events, std::size_t(v.event_count), stream);
      offsets_.upload(v.offsets, pixels, stream);
      counts_.upload(v.counts, pixels, stream);
      skip.lists.events = events_.get();
      skip.lists.offsets = offsets_.get();
      skip.lists.counts = counts_.get();
    } else if (skip.method == SkipMethod::Octree) {
      nodes_.upload(skip.octree.nodes, node_count(skip.octree), stream);
      skip.octree.nodes = nodes_.get();
    }
    if (skip.fine.bits) {
      fine_.upload(skip.fine.bits, skip.fine.word_count(), stream);
      skip.fine.bits = fine_.get();
    }
    if (skip.fine.voxels.bits) {
      voxels_.upload(skip.fine.voxels.bits, skip.fine.voxels.word_count(), stream);
      skip.fine.voxels.bits = voxels_.get();
    }
  }

 private:
  // Nodes reachable from the root (the view carries no size): children blocks are contiguous.
  static std::size_t node_count(const SkipOctreeView& v) {
    if (!v.nodes) return 0;
    std::size_t n = 1;
    std::vector<std::uint32_t> stack{0};
    while (!stack.empty()) {
      const std::uint32_t i = stack.back();
      stack.pop_back();
      const std::uint32_t c = v.nodes[i].children;
      if (c == SkipOctreeView::kNone) continue;
      n = std::max<std::size_t>(n, std::size_t(c) + 8);
      for (std::uint32_t k = 0; k < 8; ++k) stack.push_back(c + k);
    }
    return n;
  }

  DeviceBuffer<vec4> tf_;
  DeviceBuffer<std::uint32_t> bits_, offsets_, counts_;
  DeviceBuffer<RayEvent> events_;
  DeviceBuffer<SkipOctreeNode> nodes_;
  DeviceBuffer<std::uint64_t> fine_, voxels_;
};

// Launches the method's kernel. kOctree = false leaves the octree kernel out (the out-of-core path
// has no octree), which keeps instantiations and build time down.
template <class Sampler, bool kOctree = true>
void launch_cast(SkipMethod method, const RayCaster<Sampler>& caster, const RayGenerator& gen, const Box3& vbox,
                 const SkipInputs& skip, const FrameOutputs& out, cudaStream_t stream) {
  const dim3 block(16, 8);
  const dim3 grid((unsigned(gen.width) + block.x - 1) / block.x, (unsigned(gen.height) + block.y - 1) / block.y);
  switch (method) {
    case SkipMethod::None: sl_cast_none<Sampler><<<grid, block, 0, stream>>>(caster, gen, vbox, skip, out); break;
    case SkipMethod::Octree:
      if constexpr (kOctree) {
        sl_cast_octree<Sampler><<<grid, block, 0, stream>>>(caster, gen, vbox, skip, out);
      } else {
        throw std::logic_error("octree kernel not built for this sampler");
      }
      break;
    case SkipMethod::BBox:
    case SkipMethod::SparseLeap:
      sl_cast_segment_lists<Sampler><<<grid, block, 0, stream>>>(caster, gen, vbox, skip, out);
      break;
  }
  check(cudaGetLastError(), "kernel launch");
}

}  // namespace sl::cuda
