#include "core/cast/bricked_volume.h"

#include <algorithm>
#include <cstring>

#include "core/util/config.h"
#include "core/util/parallel.h"

namespace sl {

ivec3 BrickedVolume::brick_counts(const ivec3& dims) {
  return ivec3((dims.x - 1) / kCells + 1, (dims.y - 1) / kCells + 1, (dims.z - 1) / kCells + 1);
}

bool BrickedVolume::supported(const ivec3& dims, int elem_size) {
  if (elem_size != 1 && elem_size != 2) return false;
  if (dims.x <= 0 || dims.y <= 0 || dims.z <= 0) return false;
  const ivec3 n = brick_counts(dims);
  return std::int64_t(n.x) * n.y * n.z * kVoxels * elem_size + 4 <= kMaxBytes;
}

namespace {

template <class T>
void copy_bricks(const T* src, const ivec3& dims, const ivec3& n, T* dst) {
  constexpr int E = BrickedVolume::kEdge, C = BrickedVolume::kCells;
  const std::size_t sx = std::size_t(dims.x), sxy = sx * std::size_t(dims.y);
  parallel_for(0, n.z, [&](int bz) {
    for (int by = 0; by < n.y; ++by) {
      for (int bx = 0; bx < n.x; ++bx) {
        T* b = dst + ((std::size_t(bz) * n.y + by) * n.x + bx) * std::size_t(BrickedVolume::kVoxels);
        for (int lz = 0; lz < E; ++lz) {
          const int z = std::min(bz * C + lz, dims.z - 1);
          for (int ly = 0; ly < E; ++ly) {
            const int y = std::min(by * C + ly, dims.y - 1);
            const T* row = src + std::size_t(z) * sxy + std::size_t(y) * sx;
            T* out = b + (lz * E + ly) * E;
            for (int lx = 0; lx < E; ++lx) out[lx] = row[std::min(bx * C + lx, dims.x - 1)];
          }
        }
      }
    }
  });
}

}  // namespace

BrickedVolume::BrickedVolume(const void* data, const ivec3& dims, int elem_size) {
  SL_CHECK(data != nullptr && supported(dims, elem_size));
  bricks_ = brick_counts(dims);
  size_ = std::int64_t(bricks_.x) * bricks_.y * bricks_.z * kVoxels * elem_size;
  bytes_ = std::make_unique_for_overwrite<std::byte[]>(std::size_t(size_) + 4);  // every brick byte is written
  std::memset(bytes_.get() + size_, 0, 4);
  if (elem_size == 1) {
    copy_bricks(static_cast<const std::uint8_t*>(data), dims, bricks_, reinterpret_cast<std::uint8_t*>(bytes_.get()));
  } else {
    copy_bricks(static_cast<const std::uint16_t*>(data), dims, bricks_,
                reinterpret_cast<std::uint16_t*>(bytes_.get()));
  }
}

}  // namespace sl
