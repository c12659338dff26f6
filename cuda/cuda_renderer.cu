// Thin CUDA layer: memory, launches, copies. The per-ray logic is core/raycast.h, the same code the
// CPU backend runs and the CPU tests prove (DESIGN.md §1, STYLE.md #2).
#include "cuda/cuda_renderer.h"

#include <cuda_runtime.h>

#include <cstdint>
#include <vector>

#include "core/error.h"
#include "core/raycast.h"
#include "core/stats.h"

namespace sl::cuda {
namespace {

void check(cudaError_t e, const char* what) {
  if (e != cudaSuccess) throw std::runtime_error(std::string("CUDA ") + what + ": " + cudaGetErrorString(e));
}

// Device buffer owned by the host; frees in its destructor (errors there are only printed).
template <class T>
struct DeviceBuffer {
  T* ptr = nullptr;
  explicit DeviceBuffer(std::size_t n, const T* src = nullptr) {
    check(cudaMalloc(&ptr, n * sizeof(T) + 1), "cudaMalloc");
    if (src) check(cudaMemcpy(ptr, src, n * sizeof(T), cudaMemcpyHostToDevice), "cudaMemcpy");
  }
  ~DeviceBuffer() { cudaFree(ptr); }
  DeviceBuffer(const DeviceBuffer&) = delete;
  DeviceBuffer& operator=(const DeviceBuffer&) = delete;
};

template <class VT, class LT>
__global__ void cast_none_kernel(RayCaster<DenseSampler<VT, LT>> caster, RayGenerator gen, Box3 vbox, vec4* rgba,
                                 float* samples) {
  const int x = int(blockIdx.x * blockDim.x + threadIdx.x);
  const int y = int(blockIdx.y * blockDim.y + threadIdx.y);
  if (x >= gen.width || y >= gen.height) return;
  const Ray ray = gen.ray(x, y);
  const Interval iv = intersect(ray, vbox);
  const float t_entry = iv.t0 > 0.0f ? iv.t0 : 0.0f;
  RayAccum acc;
  if (iv.t1 > t_entry) {
    caster.march(ray, t_entry, 0, sample_index(iv.t1, t_entry, caster.p.inv_dt), acc);
  }
  const std::size_t i = std::size_t(y) * gen.width + x;
  rgba[i] = caster.resolve(acc);
  samples[i] = float(acc.samples);
}

template <class T>
DenseGrid<T> device_grid(const Volume& v, DeviceBuffer<T>& buf) {
  DenseGrid<T> g;
  g.data = buf.ptr;
  g.dims = v.dims();
  g.inv_spacing = 1.0f / v.desc().spacing;
  return g;
}

template <class VT, class LT>
void render_typed(const Scene& scene, const RenderSettings& s, CastParams p, Frame& frame) {
  const Volume& vol = *scene.volume;
  DeviceBuffer<VT> dvol(vol.desc().voxel_count(), vol.as<VT>());
  const std::size_t nl = scene.labels ? scene.labels->desc().voxel_count() : 0;
  DeviceBuffer<LT> dlab(nl, scene.labels ? scene.labels->as<LT>() : nullptr);
  DeviceBuffer<vec4> dtf(std::size_t(p.tf.size), p.tf.table);
  p.tf.table = dtf.ptr;
  const std::size_t nbits = p.labels.bits ? (p.labels.size + 31) / 32 : 0;
  DeviceBuffer<std::uint32_t> dbits(nbits, p.labels.bits);
  if (p.labels.bits) p.labels.bits = dbits.ptr;

  RayCaster<DenseSampler<VT, LT>> caster{p, {device_grid<VT>(vol, dvol), {}}};
  if (scene.labels) caster.volume.labels = device_grid<LT>(*scene.labels, dlab);
  const RayGenerator gen = make_ray_generator(scene.camera, s.width, s.height);
  const Box3 vbox{vec3(0.0f), vol.desc().extent()};
  const std::size_t npix = std::size_t(s.width) * s.height;
  DeviceBuffer<vec4> drgba(npix);
  DeviceBuffer<float> dsamples(npix);

  Timer t;
  const dim3 block(16, 8);
  const dim3 grid((s.width + block.x - 1) / block.x, (s.height + block.y - 1) / block.y);
  cast_none_kernel<VT, LT><<<grid, block>>>(caster, gen, vbox, drgba.ptr, dsamples.ptr);
  check(cudaGetLastError(), "kernel launch");
  check(cudaDeviceSynchronize(), "kernel");
  frame.stats.time_ms.raycast = t.ms();
  check(cudaMemcpy(frame.image.rgba.data(), drgba.ptr, npix * sizeof(vec4), cudaMemcpyDeviceToHost), "copy");
  auto& samples = frame.image.channel("samples");
  check(cudaMemcpy(samples.data(), dsamples.ptr, npix * sizeof(float), cudaMemcpyDeviceToHost), "copy");
  for (float f : samples) frame.stats.samples += std::uint64_t(f);
}

template <class VT>
void render_labels(const Scene& scene, const RenderSettings& s, const CastParams& p, Frame& f) {
  if (!scene.labels) return render_typed<VT, std::uint8_t>(scene, s, p, f);
  switch (scene.labels->type()) {
    case VoxelType::U8: return render_typed<VT, std::uint8_t>(scene, s, p, f);
    case VoxelType::U16: return render_typed<VT, std::uint16_t>(scene, s, p, f);
    default: return render_typed<VT, std::uint32_t>(scene, s, p, f);
  }
}

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

Frame render(const Scene& scene, const RenderSettings& s) {
  validate(scene, s);
  if (s.method != SkipMethod::None) {
    throw InputError("--method", std::string("the CUDA backend supports only method none so far, not ") +
                                     to_string(s.method));
  }
  Timer total;
  Frame frame;
  frame.image = Image(s.width, s.height);
  frame.stats.backend = "cuda";
  frame.stats.width = s.width;
  frame.stats.height = s.height;
  frame.stats.method = to_string(s.method);
  frame.stats.mode = to_string(s.mode);
  LabelSet label_storage;
  const CastParams p = make_cast_params(scene, s, label_storage);
  switch (scene.volume->type()) {
    case VoxelType::U8: render_labels<std::uint8_t>(scene, s, p, frame); break;
    case VoxelType::U16: render_labels<std::uint16_t>(scene, s, p, frame); break;
    case VoxelType::U32: render_labels<std::uint32_t>(scene, s, p, frame); break;
    case VoxelType::F32: render_labels<float>(scene, s, p, frame); break;
  }
  frame.stats.time_ms.total = total.ms();
  return frame;
}

}  // namespace sl::cuda
