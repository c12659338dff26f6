// Thin CUDA layer for in-core rendering: memory, launches, copies. The per-pixel logic is
// core/cast_pixel.h over core/raycast.h — the same code the CPU backend runs and the CPU tests prove
// (DESIGN.md §1, STYLE.md #2). The skipping structures (segment lists, octree) are the ones the CPU
// renderer built for the frame, uploaded here.
#include "cuda/cuda_renderer.h"

#include <cuda_runtime.h>

#include <cstdint>
#include <memory>
#include <vector>

#include "core/error.h"
#include "core/stats.h"
#include "cuda/cast_kernels.cuh"
#include "cuda/device_samplers.cuh"

namespace sl::cuda {
namespace {

// Nodes reachable from the root (the view carries no size): children blocks are contiguous.
std::size_t octree_node_count(const SkipOctreeView& v) {
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

// True for device memory (e.g. GL buffers mapped by GlListInterop); plain host memory is not.
bool on_device(const void* p) {
  cudaPointerAttributes a{};
  if (cudaPointerGetAttributes(&a, p) != cudaSuccess) {
    cudaGetLastError();
    return false;
  }
  return a.type == cudaMemoryTypeDevice || a.type == cudaMemoryTypeManaged;
}

template <class T>
DenseGrid<T> device_grid(const Volume& v, const std::byte* data) {
  DenseGrid<T> g;
  g.data = reinterpret_cast<const T*>(data);
  g.dims = v.dims();
  g.inv_spacing = 1.0f / v.desc().spacing;
  return g;
}

class InCoreCaster {
 public:
  InCoreCaster() { check(cudaStreamCreate(&stream_), "cudaStreamCreate"); }
  ~InCoreCaster() { check_noexcept(cudaStreamDestroy(stream_), "cudaStreamDestroy"); }

  void cast(const Scene& scene, const RenderSettings& s, CastParams p, SkipInputs skip, Frame& frame) {
    Timer timer;
    upload_volume(scene);
    // Per-frame inputs: transfer-function table, enabled labels, the skipping structures.
    tf_.upload(p.tf.table, std::size_t(p.tf.size), stream_);
    p.tf.table = tf_.get();
    if (p.labels.bits) {
      bits_.upload(p.labels.bits, (p.labels.size + 31) / 32, stream_);
      p.labels.bits = bits_.get();
    }
    if ((skip.method == SkipMethod::SparseLeap || skip.method == SkipMethod::BBox) && !on_device(skip.lists.events)) {
      // (Lists mapped from GL by GlListInterop are already on the device: used in place.)
      const SegmentListView& v = skip.lists;
      const std::size_t pixels = std::size_t(v.width) * std::size_t(v.height);
      events_.upload(v.events, pixels * v.capacity, stream_);
      counts_.upload(v.counts, pixels, stream_);
      skip.lists.events = events_.get();
      skip.lists.counts = counts_.get();
    } else if (skip.method == SkipMethod::Octree) {
      nodes_.upload(skip.octree.nodes, octree_node_count(skip.octree), stream_);
      skip.octree.nodes = nodes_.get();
    }
    const bool iso = s.mode == RenderMode::Iso;
    const FrameOutputs out = frame_.prepare(s.width, s.height, iso, stream_);
    const RayGenerator gen = make_ray_generator(scene.camera, s.width, s.height);
    const Box3 vbox{vec3(0.0f), scene.volume->desc().extent()};
    switch (scene.volume->type()) {
      case VoxelType::U8: launch<std::uint8_t>(scene, p, gen, vbox, skip, out); break;
      case VoxelType::U16: launch<std::uint16_t>(scene, p, gen, vbox, skip, out); break;
      case VoxelType::U32: launch<std::uint32_t>(scene, p, gen, vbox, skip, out); break;
      case VoxelType::F32: launch<float>(scene, p, gen, vbox, skip, out); break;
    }
    frame_.finish(frame, skip.method, iso, stream_);
    frame.stats.time_ms.raycast = timer.ms();
    frame.stats.backend = "cuda";
  }

 private:
  void upload_volume(const Scene& scene) {
    if (scene.volume != volume_ || scene.volume->desc().byte_size() != volume_bytes_) {
      volume_ = scene.volume;
      volume_bytes_ = volume_->desc().byte_size();
      vol_.upload(volume_->data(), volume_bytes_, stream_);
    }
    if (scene.labels != labels_ || (scene.labels && scene.labels->desc().byte_size() != labels_bytes_)) {
      labels_ = scene.labels;
      labels_bytes_ = labels_ ? labels_->desc().byte_size() : 0;
      if (labels_) lab_.upload(labels_->data(), labels_bytes_, stream_);
    }
  }

  template <class VT>
  void launch(const Scene& scene, const CastParams& p, const RayGenerator& gen, const Box3& vbox,
              const SkipInputs& skip, const FrameOutputs& out) {
    DenseAnyLabelSampler<VT> sampler;
    sampler.volume = device_grid<VT>(*scene.volume, vol_.get());
    if (scene.labels) {
      switch (scene.labels->type()) {
        case VoxelType::U8: sampler.l8 = device_grid<std::uint8_t>(*scene.labels, lab_.get()); break;
        case VoxelType::U16: sampler.l16 = device_grid<std::uint16_t>(*scene.labels, lab_.get()); break;
        case VoxelType::U32: sampler.l32 = device_grid<std::uint32_t>(*scene.labels, lab_.get()); break;
        case VoxelType::F32: throw InputError("--labels", "label volume must be of an integer type");
      }
    }
    launch_cast(skip.method, RayCaster<DenseAnyLabelSampler<VT>>{p, sampler}, gen, vbox, skip, out, stream_);
  }

  cudaStream_t stream_ = nullptr;
  const Volume* volume_ = nullptr;
  const Volume* labels_ = nullptr;
  std::uint64_t volume_bytes_ = 0, labels_bytes_ = 0;
  DeviceBuffer<std::byte> vol_, lab_;
  DeviceBuffer<vec4> tf_;
  DeviceBuffer<std::uint32_t> bits_, counts_;
  DeviceBuffer<RayEvent> events_;
  DeviceBuffer<SkipOctreeNode> nodes_;
  DeviceFrame frame_;
};

}  // namespace

DeviceInfo query_devices() {
  DeviceInfo info;
  int n = 0;
  const cudaError_t e = cudaGetDeviceCount(&n);
  if (e != cudaSuccess) {
    info.error = cudaGetErrorString(e);
    cudaGetLastError();  // clear the sticky error
    return info;
  }
  info.count = n;
  if (n > 0) {
    cudaDeviceProp prop{};
    if (cudaGetDeviceProperties(&prop, 0) == cudaSuccess) info.name = prop.name;
  } else {
    info.error = "no CUDA device";
  }
  return info;
}

InCoreRenderer::Caster make_frame_caster() {
  auto state = std::make_shared<InCoreCaster>();
  return [state](const Scene& scene, const RenderSettings& s, const CastParams& p, const SkipInputs& skip,
                 Frame& frame) { state->cast(scene, s, p, skip, frame); };
}

Frame render(const Scene& scene, const RenderSettings& s) {
  InCoreRenderer r;
  r.set_caster(make_frame_caster());
  Frame f = r.render(scene, s);
  f.stats.backend = "cuda";
  return f;
}

}  // namespace sl::cuda
