// Compile check of the shared headers (STYLE.md #1–#2): every SL_HOST_DEVICE header of core/ and
// cache/ and the per-pixel caster instantiated over the CPU samplers, in device code. nvcc builds
// this file into cuda_tests (building it is the test; the kernels below are then found in the test
// binary's fatbin by kernels_test.cpp); g++ builds the same file through shared_headers_host_test.cpp,
// which runs the host side against the CPU renderer.
#include <cstdint>

#include "cache/brick.h"
#include "cache/brick_cache.h"
#include "cache/miss_buffer.h"
#include "cache/page_table.h"
#include "cache/virtual_sampler.h"
#include "core/scene/camera.h"
#include "core/cast/cast_pixel.h"
#include "core/util/config.h"
#include "core/scene/labels.h"
#include "core/util/math.h"
#include "core/occupancy/occupancy_class.h"
#include "core/occupancy/octree_skip.h"
#include "core/util/ray.h"
#include "core/cast/raycast.h"
#include "core/recon/sampling.h"
#include "core/lists/segment_list.h"
#include "core/scene/transfer_function.h"

namespace sl::test {

// One pixel through the shared code: ray, span, method walk, resolve. Returns the pixel's alpha.
template <class Sampler>
SL_HOST_DEVICE float shared_headers_pixel(const RayCaster<Sampler>& caster, const RayGenerator& gen, const Box3& vbox,
                                          const SkipInputs& skip, int x, int y, std::uint32_t& samples) {
  Ray ray;
  float t0, t1;
  if (!pixel_span(gen, vbox, x, y, ray, t0, t1)) return 0.0f;
  RayAccum acc;
  std::uint32_t misses = 0;
  detail::cast_pixel(caster, skip, std::size_t(y) * std::size_t(gen.width) + std::size_t(x), ray, t0, t1, acc, misses);
  samples = acc.samples;
  return caster.resolve(acc).w;
}

// Segment-list building (Alg. 4–5) and the unified miss buffer on the device side.
SL_HOST_DEVICE inline std::uint32_t shared_headers_list(const Ray& ray, const Box3& box, MissBufferView misses) {
  SegmentList list;
  list.add_box(ray, box, true, OccupancyClass::NonEmpty, OccupancyClass::Empty);
  list.add_box(ray, box, false, OccupancyClass::NonEmpty, OccupancyClass::Empty);
  if (misses.table) misses.insert(BrickId::pack(0, ivec3(1, 2, 3)));
  return list.count();
}

#if defined(__CUDACC__)
template <class Sampler>
__global__ void shared_headers_compile_check(RayCaster<Sampler> caster, RayGenerator gen, Box3 vbox, SkipInputs skip,
                                             MissBufferView misses, float* out) {
  const int x = int(blockIdx.x * blockDim.x + threadIdx.x), y = int(blockIdx.y);
  if (x >= gen.width || y >= gen.height) return;
  std::uint32_t samples = 0;
  out[y * gen.width + x] = shared_headers_pixel(caster, gen, vbox, skip, x, y, samples) + float(samples) +
                           float(shared_headers_list(gen.ray(x, y), vbox, misses));
}

// Instantiates the check for in-core (DenseSampler) and out-of-core (VirtualSampler) casters.
int shared_headers_kernels() {
  const void* k[] = {
      reinterpret_cast<const void*>(&shared_headers_compile_check<DenseSampler<std::uint8_t, std::uint8_t>>),
      reinterpret_cast<const void*>(&shared_headers_compile_check<DenseSampler<float, std::uint32_t>>),
      reinterpret_cast<const void*>(&shared_headers_compile_check<VirtualSampler<std::uint16_t, std::uint16_t>>),
      reinterpret_cast<const void*>(&shared_headers_compile_check<VirtualSampler<float, std::uint32_t>>),
  };
  int n = 0;
  for (const void* p : k) n += p != nullptr;
  return n;
}
#endif

}  // namespace sl::test
