#include "cache/pyramid.h"

#include <algorithm>
#include <cstring>

#include "core/config.h"
#include "core/voxel_dispatch.h"

namespace sl {
namespace {

template <class T>
void mean_rows(const T* src, ivec3 sd, T* dst, int z0, int z1) {
  const ivec3 dd = (sd + 1) / 2;
  for (int z = z0; z < z1; ++z) {
    for (int y = 0; y < dd.y; ++y) {
      for (int x = 0; x < dd.x; ++x) {
        double fsum = 0.0;
        std::uint64_t isum = 0;
        int n = 0;
        for (int k = 2 * z; k < std::min(2 * z + 2, sd.z); ++k) {
          for (int j = 2 * y; j < std::min(2 * y + 2, sd.y); ++j) {
            const T* row = src + (std::size_t(k) * std::size_t(sd.y) + std::size_t(j)) * std::size_t(sd.x);
            for (int i = 2 * x; i < std::min(2 * x + 2, sd.x); ++i) {
              if constexpr (std::is_floating_point_v<T>) {
                fsum += double(row[i]);
              } else {
                isum += std::uint64_t(row[i]);
              }
              ++n;
            }
          }
        }
        T& out = dst[(std::size_t(z) * std::size_t(dd.y) + std::size_t(y)) * std::size_t(dd.x) + std::size_t(x)];
        if constexpr (std::is_floating_point_v<T>) {
          out = T(fsum / double(n));
        } else {
          out = T((isum + std::uint64_t(n / 2)) / std::uint64_t(n));
        }
      }
    }
  }
}

template <class T>
void mode_rows(const T* src, ivec3 sd, T* dst, int z0, int z1) {
  const ivec3 dd = (sd + 1) / 2;
  for (int z = z0; z < z1; ++z) {
    for (int y = 0; y < dd.y; ++y) {
      for (int x = 0; x < dd.x; ++x) {
        T v[8];
        int n = 0;
        for (int k = 2 * z; k < std::min(2 * z + 2, sd.z); ++k) {
          for (int j = 2 * y; j < std::min(2 * y + 2, sd.y); ++j) {
            const T* row = src + (std::size_t(k) * std::size_t(sd.y) + std::size_t(j)) * std::size_t(sd.x);
            for (int i = 2 * x; i < std::min(2 * x + 2, sd.x); ++i) {
              if (row[i] != 0) v[n++] = row[i];
            }
          }
        }
        T best = 0;
        int best_count = 0;
        for (int a = 0; a < n; ++a) {
          int c = 0;
          for (int b = 0; b < n; ++b) c += v[b] == v[a];
          if (c > best_count || (c == best_count && v[a] > best)) {
            best = v[a];
            best_count = c;
          }
        }
        dst[(std::size_t(z) * std::size_t(dd.y) + std::size_t(y)) * std::size_t(dd.x) + std::size_t(x)] = best;
      }
    }
  }
}

}  // namespace

void reduce_mean(VoxelType t, const std::byte* src, ivec3 sd, std::byte* dst, int z0, int z1) {
  dispatch_voxel(t, [&](auto tag) {
    using T = decltype(tag);
    mean_rows(reinterpret_cast<const T*>(src), sd, reinterpret_cast<T*>(dst), z0, z1);
  });
}

void reduce_mode(VoxelType t, const std::byte* src, ivec3 sd, std::byte* dst, int z0, int z1) {
  dispatch_label(
      t,
      [&](auto tag) {
        using T = decltype(tag);
        mode_rows(reinterpret_cast<const T*>(src), sd, reinterpret_cast<T*>(dst), z0, z1);
      },
      [] { SL_CHECK(!"labels must be an integer type"); });
}

void brick_read_box(const BrickLayout& layout, BrickId id, ivec3& first, ivec3& dims) {
  const ivec3 d = layout.dims(id.level());
  const ivec3 lo = glm::max(layout.brick_origin(id) - kBrickApron, ivec3(0));
  const ivec3 hi = glm::min(layout.brick_origin(id) + layout.brick_size + kBrickApron, d - 1);
  first = lo;
  dims = hi - lo + 1;
}

void fill_brick(const BrickLayout& layout, BrickId id, const std::byte* src, ivec3 src_first, ivec3 src_dims,
                int elem, std::span<std::byte> out) {
  const int n = layout.stored_size();
  SL_CHECK(out.size() == std::size_t(layout.stored_voxels()) * std::size_t(elem));
  const ivec3 d = layout.dims(id.level());
  const ivec3 start = layout.brick_origin(id) - kBrickApron;
  int xs[128];  // clamped source x of each stored column (B + 2 <= 66)
  for (int s = 0; s < n; ++s) xs[s] = std::clamp(start.x + s, 0, d.x - 1) - src_first.x;
  // The stored columns whose source is contiguous form one run: clamping only repeats the ends.
  int run0 = 0, run1 = n - 1;
  while (run0 < n - 1 && xs[run0 + 1] == xs[run0]) ++run0;
  while (run1 > run0 && xs[run1 - 1] == xs[run1]) --run1;
  for (int s = 0; s < n; ++s) SL_CHECK(xs[s] >= 0 && xs[s] < src_dims.x);
  std::byte* o = out.data();
  for (int sz = 0; sz < n; ++sz) {
    const int z = std::clamp(start.z + sz, 0, d.z - 1) - src_first.z;
    SL_CHECK(z >= 0 && z < src_dims.z);
    for (int sy = 0; sy < n; ++sy) {
      const int y = std::clamp(start.y + sy, 0, d.y - 1) - src_first.y;
      SL_CHECK(y >= 0 && y < src_dims.y);
      const std::byte* row = src + (std::size_t(z) * std::size_t(src_dims.y) + std::size_t(y)) *
                                       std::size_t(src_dims.x) * std::size_t(elem);
      for (int s = 0; s < run0; ++s) std::memcpy(o + std::size_t(s) * elem, row + std::size_t(xs[s]) * elem, elem);
      std::memcpy(o + std::size_t(run0) * elem, row + std::size_t(xs[run0]) * elem, std::size_t(run1 - run0 + 1) * elem);
      for (int s = run1 + 1; s < n; ++s) std::memcpy(o + std::size_t(s) * elem, row + std::size_t(xs[s]) * elem, elem);
      o += std::size_t(n) * elem;
    }
  }
}

}  // namespace sl
