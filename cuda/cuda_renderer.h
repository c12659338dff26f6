// CUDA backend entry points. A plain C++ header: callers never see CUDA types.
#pragma once

#include <memory>
#include <string>

#include "cache/out_of_core/cast_device.h"
#include "core/frame/in_core_renderer.h"

namespace sl::cuda {

struct DeviceInfo {
  int count = 0;
  std::string name;   // first device
  std::string error;  // why there is none
};

// Never throws: no driver or no device gives count 0 and the runtime's reason.
DeviceInfo query_devices();

// In core: an InCoreRenderer::Caster that casts on device 0 with the skipping structures the CPU
// renderer prepared (segment lists, octree), uploaded each frame; the volume is uploaded once per
// Volume. Methods none, bbox, octree, sparseleap; every mode. The returned function owns the device
// state.
InCoreRenderer::Caster make_frame_caster();

// Out of core: the device side of OutOfCoreRenderer (cache/out_of_core/cast_device.h): page table, slot pool,
// miss buffer and usage stamps in device memory, brick uploads on a stream that overlaps the frame.
struct CastDeviceOptions {
  // Sample resident bricks with the texture unit (3D CUDA array atlas, hardware trilinear; close to
  // but not bit-identical with the CPU) instead of software trilinear from a linear slot pool (the
  // default: the same SlotSampler arithmetic as the CPU). u32 volumes always use the software path.
  bool texture_atlas = false;
};
std::unique_ptr<CastDevice> make_cast_device(const CastDeviceOptions& options = {});

}  // namespace sl::cuda
