// Random voxel data for the sampling properties (tests/core/recon/sampling_simd_test.cpp,
// tests/cache/slot_sampler_simd_test.cpp): reproducible from a generated seed, with few or many
// distinct values.
#pragma once

#include <bit>
#include <cstdint>
#include <memory>
#include <type_traits>

#include "core/recon/sampling.h"
#include "core/scene/volume.h"

namespace sl::test {

template <class T>
constexpr VoxelType voxel_type() {
  if constexpr (std::is_same_v<T, std::uint8_t>) return VoxelType::U8;
  if constexpr (std::is_same_v<T, std::uint16_t>) return VoxelType::U16;
  return VoxelType::F32;
}

inline std::uint32_t bits(float v) { return std::bit_cast<std::uint32_t>(v); }

// xorshift32 values: arbitrary but reproducible from a generated seed, so volumes of thousands of
// voxels need no per-voxel generator (and shrinking works on the seed and the shape).
struct Xorshift {
  std::uint32_t h;
  std::uint32_t next() {
    h ^= h << 13;
    h ^= h >> 17;
    h ^= h << 5;
    return h;
  }
};

// Voxel values drawn from `levels` distinct values (1: a uniform volume, which takes the SSE path's
// all-equal shortcut; small: many uniform 2x2x2 cells; 0: the type's whole range).
template <class T>
T random_voxel(Xorshift& rng, std::uint32_t levels) {
  const std::uint32_t r = rng.next();
  if constexpr (std::is_floating_point_v<T>) {
    return levels ? float(r % levels) : float(std::int32_t(r)) * 1.5e-4f;
  } else {
    return T(levels ? r % levels : r);
  }
}

inline std::shared_ptr<Volume> random_volume(ivec3 dims, vec3 spacing, VoxelType t, Xorshift& rng, std::uint32_t levels) {
  auto v = std::make_shared<Volume>(VolumeDesc{dims, spacing, t});
  const std::int64_t n = std::int64_t(dims.x) * dims.y * dims.z;
  for (std::int64_t i = 0; i < n; ++i) {
    switch (t) {
      case VoxelType::U8: v->as<std::uint8_t>()[i] = random_voxel<std::uint8_t>(rng, levels); break;
      case VoxelType::U16: v->as<std::uint16_t>()[i] = random_voxel<std::uint16_t>(rng, levels); break;
      default: v->as<float>()[i] = random_voxel<float>(rng, levels); break;
    }
  }
  return v;
}

template <class T>
DenseGrid<T> grid_of(const Volume& v, vec3 spacing) {
  return DenseGrid<T>{v.as<T>(), v.dims(), 1.0f / spacing};  // inv_spacing as the renderers build it
}

}  // namespace sl::test
