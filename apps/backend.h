// Choosing the rendering backend (`--backend auto|cpu|cuda`) and the segment-list builder
// (`--lists cpu|gl`), and rendering a frame with them.
#pragma once

#include <memory>
#include <string>

#include "cache/cast_device.h"
#include "cache/out_of_core.h"
#include "core/in_core_renderer.h"

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

// A ListBuilder running on a headless GL context made here (InputError naming --lists
// when no context can be made). The function owns the context and the builder.
ListBuilder make_gl_list_builder();

// The out-of-core cast device of a backend: the CUDA device, or null (the CPU caster).
std::unique_ptr<CastDevice> make_cast_device(Backend b);

class FrameRenderer {
 public:
  explicit FrameRenderer(Backend b, ListSource lists = ListSource::Cpu);
  Frame render(const Scene& scene, const RenderSettings& settings);
  Backend backend() const { return backend_; }
  void invalidate_lists() { cpu_.invalidate_lists(); }

 private:
  Backend backend_;
  InCoreRenderer cpu_;  // prepares the skipping structures for every backend; casts for the CPU
};

inline Frame render_frame(Backend b, const Scene& scene, const RenderSettings& s) {
  FrameRenderer r(b);
  return r.render(scene, s);
}

}  // namespace sl::app
