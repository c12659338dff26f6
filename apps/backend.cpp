#include "apps/backend.h"

#include <cstdio>

#include "core/error.h"
#ifdef SL_HAVE_CUDA
#include "cuda/cuda_renderer.h"
#endif

namespace sl::app {

Backend choose_backend(const std::string& name, std::string* notice) {
  if (name == "cpu") return Backend::Cpu;
  if (name != "auto" && name != "cuda") {
    throw InputError("--backend", "unknown backend '" + name + "' (expected auto, cpu or cuda)");
  }
#ifdef SL_HAVE_CUDA
  const cuda::DeviceInfo info = cuda::query_devices();
  if (info.count > 0) return Backend::Cuda;
  if (name == "cuda") throw InputError("--backend", "cuda: no CUDA device available (" + info.error + ")");
  const std::string msg = "sparseleap: no CUDA device (" + info.error + "); using the CPU backend\n";
  if (notice) {
    *notice = msg;
  } else {
    std::fputs(msg.c_str(), stderr);
  }
  return Backend::Cpu;
#else
  (void)notice;
  if (name == "cuda") throw InputError("--backend", "cuda: this build has no CUDA backend (nvcc was not found)");
  return Backend::Cpu;
#endif
}

Frame FrameRenderer::render(const Scene& scene, const RenderSettings& settings) {
#ifdef SL_HAVE_CUDA
  if (backend_ == Backend::Cuda) return cuda::render(scene, settings);
#endif
  return cpu_.render(scene, settings);
}

}  // namespace sl::app
