// Voxel fetch and trilinear sampling by the conventions of DESIGN.md §8: voxel i's value sits at its
// centre, world (i + 0.5) * spacing; sampling clamps to the edge voxels.
#pragma once

#include <cstdint>

#include "core/config.h"
#include "core/math.h"

namespace sl {

// Dense volume of element type T, x fastest. Plain data, copyable to a device.
template <class T>
struct DenseGrid {
  const T* data = nullptr;
  ivec3 dims{0, 0, 0};
  vec3 inv_spacing{1.0f};

  SL_HOST_DEVICE float fetch(int x, int y, int z) const {
    return float(data[(std::int64_t(z) * dims.y + y) * std::int64_t(dims.x) + x]);
  }
  SL_HOST_DEVICE std::uint32_t fetch_label(int x, int y, int z) const {
    return std::uint32_t(data[(std::int64_t(z) * dims.y + y) * std::int64_t(dims.x) + x]);
  }

  // Trilinear sample at world position p.
  SL_HOST_DEVICE float sample(const vec3& p) const {
    vec3 u = p * inv_spacing - 0.5f;  // continuous voxel coordinate, voxel centres at integers
    u = glm::clamp(u, vec3(0.0f), vec3(dims - 1));
    const int x0 = int(u.x), y0 = int(u.y), z0 = int(u.z);  // u >= 0, so int() == floor
    const int x1 = x0 + 1 < dims.x ? x0 + 1 : x0;
    const int y1 = y0 + 1 < dims.y ? y0 + 1 : y0;
    const int z1 = z0 + 1 < dims.z ? z0 + 1 : z0;
    const float fx = u.x - float(x0), fy = u.y - float(y0), fz = u.z - float(z0);
    const std::int64_t sx = dims.x, sxy = std::int64_t(dims.x) * dims.y;
    const T* b = data;
    const std::int64_t r00 = z0 * sxy + y0 * sx, r01 = z0 * sxy + y1 * sx;
    const std::int64_t r10 = z1 * sxy + y0 * sx, r11 = z1 * sxy + y1 * sx;
    const float c00 = float(b[r00 + x0]) + fx * (float(b[r00 + x1]) - float(b[r00 + x0]));
    const float c01 = float(b[r01 + x0]) + fx * (float(b[r01 + x1]) - float(b[r01 + x0]));
    const float c10 = float(b[r10 + x0]) + fx * (float(b[r10 + x1]) - float(b[r10 + x0]));
    const float c11 = float(b[r11 + x0]) + fx * (float(b[r11 + x1]) - float(b[r11 + x0]));
    const float c0 = c00 + fy * (c01 - c00);
    const float c1 = c10 + fy * (c11 - c10);
    return c0 + fz * (c1 - c0);
  }

  // The voxel containing world position p (nearest-neighbour lookup for labels), clamped.
  SL_HOST_DEVICE std::uint32_t label_at(const vec3& p) const {
    const vec3 u = p * inv_spacing;
    int x = int(glm::floor(u.x)), y = int(glm::floor(u.y)), z = int(glm::floor(u.z));
    x = x < 0 ? 0 : (x >= dims.x ? dims.x - 1 : x);
    y = y < 0 ? 0 : (y >= dims.y ? dims.y - 1 : y);
    z = z < 0 ? 0 : (z >= dims.z ? dims.z - 1 : z);
    return fetch_label(x, y, z);
  }

  // Central-difference gradient in world units, one voxel apart.
  SL_HOST_DEVICE vec3 gradient(const vec3& p, const vec3& spacing) const {
    const vec3 hx(spacing.x, 0, 0), hy(0, spacing.y, 0), hz(0, 0, spacing.z);
    return vec3((sample(p + hx) - sample(p - hx)) / (2.0f * spacing.x),
                (sample(p + hy) - sample(p - hy)) / (2.0f * spacing.y),
                (sample(p + hz) - sample(p - hz)) / (2.0f * spacing.z));
  }
};

}  // namespace sl
