// Choosing the rendering backend (`--backend auto|cpu|cuda`), the segment-list builder
// (`--lists cpu|gl`) and the CUDA brick sampler (`--cuda-sampler slots|atlas`), and rendering in core
// with them.
#pragma once

#include <memory>
#include <string>

#include "cache/out_of_core/cast_device.h"
#include "cache/out_of_core/renderer.h"
#include "core/frame/in_core_renderer.h"

namespace sl::app {

enum class Backend { Cpu, Cuda };

// auto: CUDA when a device is present, else CPU (saying why on stderr); cuda: InputError when this
// build has no CUDA backend or no CUDA device is present.
// With `notice` set, the fallback message is stored there instead of printed (print it once every
// other check has passed, so bad input stays one line).
Backend choose_backend(const std::string& name, std::string* notice = nullptr);

// Who builds the SparseLeap segment lists: the CPU tile builder, or OpenGL's rasterizer (headless
// EGL, GlSegmentListBuilder) with the lists read back for the caster. InputError for anything else,
// or for gl in a build without the GL backend.
enum class ListSource { Cpu, Gl };
ListSource parse_list_source(const std::string& name);

// A ListBuilder running on a headless GL context made here (InputError naming --lists when no context
// can be made). The function owns the context and the builder; a GL context is current on one thread,
// so make it on the thread that renders.
ListBuilder make_gl_list_builder();

// How the CUDA cast device samples the out-of-core brick cache: `slots`, software trilinear from a
// linear slot pool (the CPU's arithmetic, the same image), or `atlas`, the texture unit's hardware
// trilinear over a 3D texture atlas (CastDeviceOptions::texture_atlas; close to, not bit-identical
// with, the CPU). InputError for anything else.
enum class CudaSampler { Slots, Atlas };
CudaSampler parse_cuda_sampler(const std::string& name);

// The out-of-core cast device of a backend: the CUDA device (sampling as `sampler` says), or null
// (the CPU caster).
std::unique_ptr<CastDevice> make_cast_device(Backend b, CudaSampler sampler);

class FrameRenderer {
 public:
  explicit FrameRenderer(Backend b, ListSource lists = ListSource::Cpu);
  Frame render(const Scene& scene, const RenderSettings& settings);
  void invalidate_lists() { cpu_.invalidate_lists(); }

 private:
  Backend backend_;
  InCoreRenderer cpu_;  // prepares the skipping structures for every backend; casts for the CPU
};

}  // namespace sl::app
