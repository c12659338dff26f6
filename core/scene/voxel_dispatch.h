// The voxel element types (DESIGN.md "Data model": u8/u16/f32 intensities, u16/u32 labels) and the one way
// from a run-time type to the element type of templated code: every typed loop, sampler
// instantiation and kernel launch goes through dispatch_voxel / dispatch_label instead of its own
// switch. core/scene/volume.h includes this; it needs nothing but the enum.
#pragma once

#include <cstdint>

#include "core/util/config.h"

namespace sl {

enum class VoxelType : std::uint8_t { U8 = 0, U16 = 1, U32 = 2, F32 = 3 };

SL_HOST_DEVICE inline int voxel_size(VoxelType t) {
  return t == VoxelType::U8 ? 1 : t == VoxelType::U16 ? 2 : 4;
}

// Calls f(T{}) with T the element type of t: std::uint8_t, std::uint16_t, std::uint32_t or float, and
// returns what f returns (the same type for every T). Typical use:
//   dispatch_voxel(v.type(), [&](auto tag) { using T = decltype(tag); run<T>(v.as<T>()); });
template <class F>
SL_HOST_DEVICE decltype(auto) dispatch_voxel(VoxelType t, F&& f) {
  switch (t) {
    case VoxelType::U8: return f(std::uint8_t{});
    case VoxelType::U16: return f(std::uint16_t{});
    case VoxelType::U32: return f(std::uint32_t{});
    case VoxelType::F32: break;
  }
  return f(float{});
}

// Label volumes hold integer ids only (DESIGN.md "Data model"): f(T{}) for u8, u16 and u32. F32 is the
// caller's error: on_float() runs instead (it throws, or returns what f would).
template <class F, class OnFloat>
SL_HOST_DEVICE decltype(auto) dispatch_label(VoxelType t, F&& f, OnFloat&& on_float) {
  switch (t) {
    case VoxelType::U8: return f(std::uint8_t{});
    case VoxelType::U16: return f(std::uint16_t{});
    case VoxelType::U32: return f(std::uint32_t{});
    case VoxelType::F32: break;
  }
  return on_float();
}

}  // namespace sl
