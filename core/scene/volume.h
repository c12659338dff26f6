// In-memory volume description and storage (DESIGN.md "Data model"), and the plain view that casters read.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "core/util/config.h"
#include "core/util/math.h"
#include "core/scene/voxel_dispatch.h"

namespace sl {

const char* to_string(VoxelType t);

struct VolumeDesc {
  ivec3 dims{0, 0, 0};
  vec3 spacing{1.0f, 1.0f, 1.0f};
  VoxelType type = VoxelType::U8;

  std::uint64_t voxel_count() const {
    return std::uint64_t(dims.x) * std::uint64_t(dims.y) * std::uint64_t(dims.z);
  }
  std::uint64_t byte_size() const { return voxel_count() * std::uint64_t(voxel_size(type)); }
  // World-space box is [0, dims * spacing] (voxel i's centre at (i + 0.5) * spacing).
  vec3 extent() const { return vec3(dims) * spacing; }
  float min_spacing() const { return glm::min(spacing.x, glm::min(spacing.y, spacing.z)); }
};

// The voxel sizes a store's metadata may declare (an NGFF scale, a precomputed resolution), in any
// unit: a size outside this range (0, denormal, 1e30) would make the volume's world box, and every
// camera placed around it, degenerate, so it is refused as the metadata's fault.
inline constexpr double kMinVoxelSize = 1e-12, kMaxVoxelSize = 1e12;
// "" when `v` is a usable voxel size, else why not ("is not a number", "is outside 1e-12..1e12").
std::string voxel_size_problem(double v);

// Throws InputError naming `file` when dims/spacing are zero, negative, non-finite or so large that the
// voxel count overflows or cannot be held in memory (`max_bytes`).
void validate_desc(const VolumeDesc& d, const std::string& file,
                   std::uint64_t max_bytes = std::uint64_t(64) << 30);

// Plain, pointer-and-size view of a dense volume (x fastest). Copyable to a device.
struct VolumeView {
  const void* data = nullptr;
  ivec3 dims{0, 0, 0};
  vec3 spacing{1.0f, 1.0f, 1.0f};
  VoxelType type = VoxelType::U8;

  SL_HOST_DEVICE std::uint64_t index(int x, int y, int z) const {
    return (std::uint64_t(z) * std::uint64_t(dims.y) + std::uint64_t(y)) * std::uint64_t(dims.x) +
           std::uint64_t(x);
  }
  // Raw value as float (u8/u16/u32 raw integers, f32 as is).
  SL_HOST_DEVICE float value(int x, int y, int z) const {
    const std::uint64_t i = index(x, y, z);
    return dispatch_voxel(type, [&](auto tag) { return float(static_cast<const decltype(tag)*>(data)[i]); });
  }
  SL_HOST_DEVICE std::uint32_t label(int x, int y, int z) const {
    const std::uint64_t i = index(x, y, z);
    return dispatch_voxel(type, [&](auto tag) { return std::uint32_t(static_cast<const decltype(tag)*>(data)[i]); });
  }
};

// Owning dense volume on the host.
class Volume {
 public:
  Volume() = default;
  explicit Volume(const VolumeDesc& desc, const std::string& origin = "volume");

  const VolumeDesc& desc() const { return desc_; }
  const ivec3& dims() const { return desc_.dims; }
  VoxelType type() const { return desc_.type; }
  bool empty() const { return bytes_.empty(); }

  std::byte* data() { return bytes_.data(); }
  const std::byte* data() const { return bytes_.data(); }
  template <class T> T* as() { return reinterpret_cast<T*>(bytes_.data()); }
  template <class T> const T* as() const { return reinterpret_cast<const T*>(bytes_.data()); }

  VolumeView view() const { return VolumeView{bytes_.data(), desc_.dims, desc_.spacing, desc_.type}; }
  float value(int x, int y, int z) const { return view().value(x, y, z); }
  std::uint32_t label(int x, int y, int z) const { return view().label(x, y, z); }
  // Stores v converted to the voxel type (rounded and clamped for integer types).
  void set(int x, int y, int z, float v);
  void set_spacing(const vec3& s) { desc_.spacing = s; }

 private:
  VolumeDesc desc_;
  std::vector<std::byte> bytes_;
};

// Largest label id in an integer volume (0 for an empty one); parallel.
std::uint32_t max_label(const Volume& labels);
// Smallest and largest raw value; parallel.
vec2 value_range(const Volume& v);

}  // namespace sl
