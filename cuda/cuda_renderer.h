// CUDA backend entry points. A plain C++ header: callers never see CUDA types.
#pragma once

#include <string>

#include "core/cpu_renderer.h"

namespace sl::cuda {

struct DeviceInfo {
  int count = 0;
  std::string name;   // first device
  std::string error;  // why there is none
};

// Never throws: no driver or no device gives count 0 and the runtime's reason.
DeviceInfo query_devices();

// Renders on device 0 with the same sample grid and per-sample code as the CPU backend.
// Supported now: method `none`. Throws InputError for what this backend does not support yet.
Frame render(const Scene& scene, const RenderSettings& settings);

}  // namespace sl::cuda
