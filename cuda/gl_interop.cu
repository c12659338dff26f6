// CUDA <-> OpenGL buffer interop for the segment lists (DESIGN.md §1: "Lists are handed to CUDA by
// buffer interop"): the GL builder's SSBOs are registered once and mapped per frame, so the kernels
// read the lists where the rasterizer wrote them. COMPILED ONLY: no GPU on the development machines,
// so this path has never run (README, "CUDA backend").
#include <cuda_gl_interop.h>
#include <cuda_runtime.h>

#include "cuda/cuda_renderer.h"
#include "cuda/cuda_util.h"

namespace sl::cuda {

struct GlListInterop::Impl {
  cudaGraphicsResource_t resources[2] = {nullptr, nullptr};
  bool mapped = false;
};

GlListInterop::GlListInterop(unsigned int events_buffer, unsigned int counts_buffer) : impl_(std::make_unique<Impl>()) {
  // Read-only for CUDA: the lists are written by GL and only read by the kernels.
  check(cudaGraphicsGLRegisterBuffer(&impl_->resources[0], events_buffer, cudaGraphicsRegisterFlagsReadOnly),
        "cudaGraphicsGLRegisterBuffer (events)");
  check(cudaGraphicsGLRegisterBuffer(&impl_->resources[1], counts_buffer, cudaGraphicsRegisterFlagsReadOnly),
        "cudaGraphicsGLRegisterBuffer (counts)");
}

GlListInterop::~GlListInterop() {
  if (impl_->mapped) check_noexcept(cudaGraphicsUnmapResources(2, impl_->resources, nullptr), "unmap");
  for (cudaGraphicsResource_t r : impl_->resources) {
    if (r) check_noexcept(cudaGraphicsUnregisterResource(r), "cudaGraphicsUnregisterResource");
  }
}

SegmentListView GlListInterop::map(int width, int height, std::uint32_t capacity) {
  if (!impl_->mapped) {
    check(cudaGraphicsMapResources(2, impl_->resources, nullptr), "cudaGraphicsMapResources");
    impl_->mapped = true;
  }
  void* events = nullptr;
  void* counts = nullptr;
  std::size_t events_bytes = 0, counts_bytes = 0;
  check(cudaGraphicsResourceGetMappedPointer(&events, &events_bytes, impl_->resources[0]), "mapped pointer (events)");
  check(cudaGraphicsResourceGetMappedPointer(&counts, &counts_bytes, impl_->resources[1]), "mapped pointer (counts)");
  const std::size_t pixels = std::size_t(width) * std::size_t(height);
  if (events_bytes < pixels * capacity * sizeof(RayEvent) || counts_bytes < pixels * sizeof(std::uint32_t)) {
    throw std::runtime_error("GL list buffers are smaller than the image's lists");
  }
  return SegmentListView{static_cast<const RayEvent*>(events), static_cast<const std::uint32_t*>(counts), width, height,
                         capacity};
}

void GlListInterop::unmap() {
  if (!impl_->mapped) return;
  check(cudaGraphicsUnmapResources(2, impl_->resources, nullptr), "cudaGraphicsUnmapResources");
  impl_->mapped = false;
}

}  // namespace sl::cuda
