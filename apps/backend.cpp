#include "apps/backend.h"

#include <cstdio>

#include "core/util/error.h"
#include "core/lists/segment_list_builder.h"
#ifdef SL_HAVE_CUDA
#include "cuda/cuda_renderer.h"
#endif
#ifdef SL_HAVE_GL
#include "gl/gl_context.h"
#include "gl/gl_segment_list_builder.h"
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

ListSource parse_list_source(const std::string& name) {
  if (name == "cpu") return ListSource::Cpu;
  if (name != "gl") throw InputError("--lists", "unknown list builder '" + name + "' (expected cpu or gl)");
#ifndef SL_HAVE_GL
  throw InputError("--lists", "gl: this build has no OpenGL backend (libepoxy/GLFW were not found)");
#endif
  return ListSource::Gl;
}

ListBuilder make_gl_list_builder() {
#ifdef SL_HAVE_GL
  struct Gl {
    std::unique_ptr<GlContext> context;
    std::unique_ptr<GlSegmentListBuilder> builder;
  };
  auto gl = std::make_shared<Gl>();
  try {
    gl->context = GlContext::create_headless();
  } catch (const GlError& e) {
    throw InputError("--lists", std::string("gl: no OpenGL context: ") + e.what());
  }
  gl->context->make_current();
  gl->builder = std::make_unique<GlSegmentListBuilder>(*gl->context);
  return [gl](const OccupancyGeometry& geometry, std::span<const VisibilityEntry> order, const RayGenerator& gen,
              SegmentListBuffer& out, float eps) {
    gl->context->make_current();
    return gl->builder->build_segment_lists(geometry, order, gen, out, eps).lists;
  };
#else
  throw InputError("--lists", "gl: this build has no OpenGL backend");
#endif
}

CudaSampler parse_cuda_sampler(const std::string& name) {
  if (name == "slots") return CudaSampler::Slots;
  if (name == "atlas") return CudaSampler::Atlas;
  throw InputError("--cuda-sampler", "unknown sampler '" + name + "' (expected slots or atlas)");
}

std::unique_ptr<CastDevice> make_cast_device(Backend b, CudaSampler sampler) {
#ifdef SL_HAVE_CUDA
  if (b == Backend::Cuda) {
    cuda::CastDeviceOptions options;
    options.texture_atlas = sampler == CudaSampler::Atlas;
    return cuda::make_cast_device(options);
  }
#else
  (void)b;
  (void)sampler;
#endif
  return nullptr;
}

FrameRenderer::FrameRenderer(Backend b, ListSource lists) : backend_(b) {
#ifdef SL_HAVE_CUDA
  if (b == Backend::Cuda) cpu_.set_caster(cuda::make_frame_caster());
#endif
  if (lists == ListSource::Gl) cpu_.set_list_builder(make_gl_list_builder());
}

Frame FrameRenderer::render(const Scene& scene, const RenderSettings& settings) {
  Frame f = cpu_.render(scene, settings);
  if (backend_ == Backend::Cuda) f.stats.backend = "cuda";
  return f;
}

}  // namespace sl::app
