// A dense u8/u16 volume copied into bricks of 8³ cells for the CPU's batched DVR (core/cast/sample_batch.h):
// brick (bx, by, bz) stores the 9³ voxels (8b + l, clamped to the volume) for l = 0..8 on each axis, x
// fastest, so every trilinear cell whose lower corner lies in the brick has all eight voxels there —
// the +1 neighbours need no clamping (the apron holds the clamped edge, as DenseGrid::sample_coord
// repeats it) and a ray's samples stay within a few cache lines per brick instead of touching new
// x-rows in other planes at every voxel step (the dense layout). The same voxels, so the same values
// bit for bit. It costs (9/8)³ ≈ 1.42 times the volume's bytes beside it; host only.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>

#include "core/util/math.h"

namespace sl {

class BrickedVolume {
 public:
  static constexpr int kCells = 8;              // cells per brick edge
  static constexpr int kEdge = kCells + 1;      // stored voxels per brick edge
  static constexpr int kVoxels = kEdge * kEdge * kEdge;
  // The batch addresses bytes with 32-bit lane offsets: bricked volumes above this size are not made
  // (the batch then reads the dense rows).
  static constexpr std::int64_t kMaxBytes = std::int64_t(1) << 30;

  // Bricks per axis for a volume of `dims` (every cell x0 in [0, dims - 1] has its brick x0 / 8).
  static ivec3 brick_counts(const ivec3& dims);
  // Whether a volume of these dims and element size (1 or 2 bytes) gets bricks.
  static bool supported(const ivec3& dims, int elem_size);

  BrickedVolume() = default;
  // Copies `data` (x fastest; supported(dims, elem_size) must hold). Parallel over the brick slabs.
  BrickedVolume(const void* data, const ivec3& dims, int elem_size);

  const std::byte* data() const { return bytes_.get(); }  // null: none
  ivec3 bricks() const { return bricks_; }
  // Bytes of the bricks; the allocation has 4 more, which the batch's 4-byte gathers may read past the
  // last voxel (their upper bytes are never used).
  std::int64_t bytes() const { return size_; }

 private:
  std::unique_ptr<std::byte[]> bytes_;
  ivec3 bricks_{0};
  std::int64_t size_ = 0;
};

}  // namespace sl
