// The 2x reductions that define level l + 1 from level l (DESIGN.md §3), and copying a brick with its
// clamped apron out of a dense array. Shared by MemoryVolumeSource (whole-volume pyramid) and the
// procedural source (per-brick reduction of synthesised level-0 voxels), so both define coarse
// levels identically.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include "cache/brick.h"
#include "core/math.h"
#include "core/volume.h"

namespace sl {

// Level l + 1 voxel v is the reduction of level-l voxels 2v + {0,1}³ that exist (an odd edge takes
// what exists). src has dims sd (x fastest); dst receives ceil(sd / 2). Rows z of dst in [z0, z1).
//  - Intensity: mean, rounded half up for integer types ((sum + n/2) / n), in double then rounded to
//    float for f32.
//  - Labels: the most frequent non-zero label; ties go to the larger id; all zero gives 0.
void reduce_mean(VoxelType t, const std::byte* src, ivec3 sd, std::byte* dst, int z0, int z1);
void reduce_mode(VoxelType t, const std::byte* src, ivec3 sd, std::byte* dst, int z0, int z1);

// Fills a brick's (B + 2)³ stored voxels of `elem` bytes each: stored voxel s holds level voxel
// clamp(origin - 1 + s, 0, level_dims - 1), read from `src`, a dense array of dims src_dims holding
// level voxels [src_first, src_first + src_dims). src must cover every clamped voxel the brick needs.
void fill_brick(const BrickLayout& layout, BrickId id, const std::byte* src, ivec3 src_first, ivec3 src_dims,
                int elem, std::span<std::byte> out);

// The level-voxel box a brick reads, apron included, clamped to the level: [first, first + dims).
void brick_read_box(const BrickLayout& layout, BrickId id, ivec3& first, ivec3& dims);

}  // namespace sl
