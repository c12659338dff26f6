// Thin CUDA layer for in-core rendering: memory, launches, copies. The per-pixel logic is
// core/cast/cast_pixel.h over core/cast/raycast.h — the same code the CPU backend runs and the CPU tests prove
// (DESIGN.md "What the program is", STYLE.md #2). The skipping structures (segment lists, octree) are the ones the CPU
// renderer built for the frame, uploaded here.
#include "cuda/cuda_renderer.h"

#include <cuda_runtime.h>

#include <cstdint>
#include <memory>

#include "core/util/error.h"
#include "core/frame/stats.h"
#include "cuda/cast_kernels.cuh"
#include "cuda/device_samplers.cuh"

namespace sl::cuda {
namespace {

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
    inputs_.upload(p, skip, stream_);  // transfer-function table, enabled labels, skipping structures
    const bool depth = writes_depth(s.mode);
    const FrameOutputs out = frame_.prepare(s.width, s.height, depth, stream_);
    const RayGenerator gen = make_ray_generator(scene.camera, s.width, s.height);
    const Box3 vbox{vec3(0.0f), scene.volume->desc().extent()};
    dispatch_voxel(scene.volume->type(),
                   [&](auto tag) { launch<decltype(tag)>(scene, p, gen, vbox, skip, out); });
    frame_.finish(frame, skip.method, depth, stream_);
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
  FrameInputs inputs_;
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

}  // namespace sl::cuda
