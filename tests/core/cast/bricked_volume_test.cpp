// The bricked copy of a volume the CPU batch reads (core/cast/bricked_volume.h): every stored voxel is the
// source voxel at the clamped position, for any dims (edges, one-voxel axes, dims not a multiple of 8)
// and both element sizes; what it supports and rejects.
#include "core/cast/bricked_volume.h"

#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include <algorithm>
#include <cstring>
#include <vector>

namespace sl {
namespace {

template <class T>
void check_layout(const ivec3& dims) {
  std::vector<T> src(std::size_t(dims.x) * dims.y * dims.z);
  for (std::size_t i = 0; i < src.size(); ++i) src[i] = T((i * 2654435761u) >> 7);
  const BrickedVolume b(src.data(), dims, int(sizeof(T)));
  const ivec3 n = b.bricks();
  RC_ASSERT(n == BrickedVolume::brick_counts(dims));
  RC_ASSERT(b.bytes() == std::int64_t(n.x) * n.y * n.z * BrickedVolume::kVoxels * std::int64_t(sizeof(T)));
  constexpr int E = BrickedVolume::kEdge, C = BrickedVolume::kCells;
  const T* out = reinterpret_cast<const T*>(b.data());
  for (int bz = 0; bz < n.z; ++bz)
    for (int by = 0; by < n.y; ++by)
      for (int bx = 0; bx < n.x; ++bx)
        for (int lz = 0; lz < E; ++lz)
          for (int ly = 0; ly < E; ++ly)
            for (int lx = 0; lx < E; ++lx) {
              const int x = std::min(bx * C + lx, dims.x - 1), y = std::min(by * C + ly, dims.y - 1),
                        z = std::min(bz * C + lz, dims.z - 1);
              const std::size_t at = ((std::size_t(bz) * n.y + by) * n.x + bx) * BrickedVolume::kVoxels +
                                     std::size_t((lz * E + ly) * E + lx);
              RC_ASSERT(out[at] == src[(std::size_t(z) * dims.y + y) * dims.x + x]);
            }
  // Every cell's brick exists: the last cell of each axis lies in the last brick.
  RC_ASSERT((dims.x - 1) / C == n.x - 1 && (dims.y - 1) / C == n.y - 1 && (dims.z - 1) / C == n.z - 1);
}

RC_GTEST_PROP(BrickedVolumeProperty, EveryVoxelIsTheClampedSourceVoxel, ()) {
  const ivec3 dims(*rc::gen::inRange(1, 27), *rc::gen::inRange(1, 27), *rc::gen::inRange(1, 27));
  if (*rc::gen::arbitrary<bool>()) {
    check_layout<std::uint8_t>(dims);
  } else {
    check_layout<std::uint16_t>(dims);
  }
}

TEST(BrickedVolume, SupportsU8AndU16UpToItsByteLimit) {
  EXPECT_TRUE(BrickedVolume::supported(ivec3(1, 1, 1), 1));
  EXPECT_TRUE(BrickedVolume::supported(ivec3(256, 256, 256), 2));
  EXPECT_FALSE(BrickedVolume::supported(ivec3(256, 256, 256), 4));  // f32: the batch does not read it
  EXPECT_FALSE(BrickedVolume::supported(ivec3(0, 4, 4), 1));
  // 1024³ u8: 128³ bricks of 729 bytes, 1.53 GB, past the 1 GiB the 32-bit lane offsets allow.
  EXPECT_FALSE(BrickedVolume::supported(ivec3(1024, 1024, 1024), 1));
  EXPECT_EQ(BrickedVolume::brick_counts(ivec3(8, 9, 17)), ivec3(1, 2, 3));
}

}  // namespace
}  // namespace sl
