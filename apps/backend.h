// Choosing the rendering backend (`--backend auto|cpu|cuda`) and rendering a frame with it.
#pragma once

#include <memory>
#include <string>

#include "core/cpu_renderer.h"

namespace sl::app {

enum class Backend { Cpu, Cuda };

// auto: CUDA when a device is present, else CPU (saying why on stderr); cuda: InputError when this
// build has no CUDA backend or no CUDA device is present.
// With `notice` set, the fallback message is stored there instead of printed (print it once every
// other check has passed, so bad input stays one line).
Backend choose_backend(const std::string& name, std::string* notice = nullptr);

class FrameRenderer {
 public:
  explicit FrameRenderer(Backend b) : backend_(b) {}
  Frame render(const Scene& scene, const RenderSettings& settings);
  Backend backend() const { return backend_; }
  void invalidate_lists() { cpu_.invalidate_lists(); }

 private:
  Backend backend_;
  CpuRenderer cpu_;
};

inline Frame render_frame(Backend b, const Scene& scene, const RenderSettings& s) {
  FrameRenderer r(b);
  return r.render(scene, s);
}

}  // namespace sl::app
