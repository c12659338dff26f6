#include "core/scene/volume.h"

#include <cmath>
#include <cstring>
#include <limits>
#include <type_traits>

#include "core/util/error.h"
#include "core/util/parallel.h"

namespace sl {

const char* to_string(VoxelType t) {
  switch (t) {
    case VoxelType::U8: return "u8";
    case VoxelType::U16: return "u16";
    case VoxelType::U32: return "u32";
    case VoxelType::F32: return "f32";
  }
  return "?";
}

std::string voxel_size_problem(double v) {
  if (std::isnan(v)) return "is not a number";
  if (!(v > 0.0)) return "is not positive";
  if (!(v >= kMinVoxelSize && v <= kMaxVoxelSize)) return "is outside 1e-12..1e12";
  return {};
}

void validate_desc(const VolumeDesc& d, const std::string& file, std::uint64_t max_bytes) {
  for (int a = 0; a < 3; ++a) {
    if (d.dims[a] <= 0) {
      throw InputError(file, "dimension " + std::to_string(a) + " is " + std::to_string(d.dims[a]) +
                                 " (must be positive)");
    }
    if (!(d.spacing[a] > 0.0f) || !std::isfinite(d.spacing[a])) {
      throw InputError(file, "spacing along axis " + std::to_string(a) + " is not a positive number");
    }
  }
  // Overflow-safe product: each dim < 2^31, so two dims fit in 62 bits; check the third by division.
  const std::uint64_t xy = std::uint64_t(d.dims.x) * std::uint64_t(d.dims.y);
  const std::uint64_t limit = max_bytes / std::uint64_t(voxel_size(d.type));
  if (xy > limit || std::uint64_t(d.dims.z) > limit / xy) {
    throw InputError(file, "dims " + std::to_string(d.dims.x) + "x" + std::to_string(d.dims.y) + "x" +
                               std::to_string(d.dims.z) + " of " + to_string(d.type) +
                               " exceed the in-memory limit of " + std::to_string(max_bytes >> 20) +
                               " MiB");
  }
}

Volume::Volume(const VolumeDesc& desc, const std::string& origin) : desc_(desc) {
  validate_desc(desc_, origin);
  bytes_.assign(desc_.byte_size(), std::byte{0});
}

void Volume::set(int x, int y, int z, float v) {
  const std::uint64_t i = view().index(x, y, z);
  auto clampi = [&](double lo, double hi) { return std::fmin(std::fmax(std::nearbyint(v), lo), hi); };
  dispatch_voxel(desc_.type, [&](auto tag) {
    using T = decltype(tag);
    if constexpr (std::is_floating_point_v<T>) {
      as<T>()[i] = v;
    } else {
      as<T>()[i] = T(clampi(0, double(std::numeric_limits<T>::max())));
    }
  });
}

std::uint32_t max_label(const Volume& labels) {
  const VolumeView v = labels.view();
  const std::uint64_t n = labels.desc().voxel_count();
  return parallel_reduce(
      std::uint64_t(0), n, std::uint64_t(1) << 16, std::uint32_t(0),
      [&](std::uint64_t lo, std::uint64_t hi, std::uint32_t m) {
        for (std::uint64_t i = lo; i < hi; ++i) {
          const int x = int(i % std::uint64_t(v.dims.x));
          const std::uint64_t yz = i / std::uint64_t(v.dims.x);
          const std::uint32_t l = v.label(x, int(yz % std::uint64_t(v.dims.y)), int(yz / std::uint64_t(v.dims.y)));
          m = l > m ? l : m;
        }
        return m;
      },
      [](std::uint32_t a, std::uint32_t b) { return a > b ? a : b; });
}

vec2 value_range(const Volume& vol) {
  const VolumeView v = vol.view();
  const std::uint64_t n = vol.desc().voxel_count();
  // min and max are exact in any grouping. Only finite voxels count: a NaN is never selected, and a
  // ±Inf voxel would give a non-finite default transfer function (it clamps to the ends instead).
  return parallel_reduce(
      std::uint64_t(0), n, std::uint64_t(1) << 16, vec2(INFINITY, -INFINITY),
      [&](std::uint64_t lo, std::uint64_t hi, vec2 m) {
        for (std::uint64_t i = lo; i < hi; ++i) {
          const int x = int(i % std::uint64_t(v.dims.x));
          const std::uint64_t yz = i / std::uint64_t(v.dims.x);
          const float f = v.value(x, int(yz % std::uint64_t(v.dims.y)), int(yz / std::uint64_t(v.dims.y)));
          if (!std::isfinite(f)) continue;
          m.x = f < m.x ? f : m.x;
          m.y = f > m.y ? f : m.y;
        }
        return m;
      },
      [](vec2 a, vec2 b) { return vec2(glm::min(a.x, b.x), glm::max(a.y, b.y)); });
}

}  // namespace sl
