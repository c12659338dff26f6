// The 2x reductions that define level l + 1 from level l (DESIGN.md "Data model"), and copying a brick with its
// clamped apron out of a dense array. Shared by MemoryVolumeSource (whole-volume pyramid) and the
// procedural source (per-brick reduction of synthesised level-0 voxels), so both define coarse
// levels identically.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "cache/brick.h"
#include "core/util/math.h"
#include "core/scene/volume.h"

namespace sl {

// Which intensity pyramid a source renders its levels >= 1 from (level 0 is the data either way).
//  - Mean: the average of the voxels below; right for dense data, where a coarse voxel should look
//    like the blur of its region.
//  - Max: the largest voxel below (reduce_max); keeps sparse structure (thin neurites, spots) that
//    the mean averages under the transfer function's threshold, at the cost of thickening it.
// The bounds pyramid bounds both, so culling is the same for either (DESIGN.md "Virtual memory").
enum class PyramidKind { Mean, Max };
const char* pyramid_name(PyramidKind k);
// "mean" or "max"; anything else throws InputError(what, ...).
PyramidKind parse_pyramid_kind(const std::string& text, const std::string& what);
// The intensity reduction of one level step of pyramid `k` (reduce_mean or reduce_max).
using ReduceFn = void (*)(VoxelType, const std::byte*, ivec3, std::byte*, int, int);
ReduceFn intensity_reduction(PyramidKind k);

// Level l + 1 voxel v is the reduction of level-l voxels 2v + {0,1}³ that exist (an odd edge takes
// what exists). src has dims sd (x fastest); dst receives ceil(sd / 2). Rows z of dst in [z0, z1).
//  - Intensity: mean, rounded half up for integer types ((sum + n/2) / n), in double then rounded to
//    float for f32.
//  - Labels: the most frequent non-zero label; ties go to the larger id; all zero gives 0.
void reduce_mean(VoxelType t, const std::byte* src, ivec3 sd, std::byte* dst, int z0, int z1);
void reduce_mode(VoxelType t, const std::byte* src, ivec3 sd, std::byte* dst, int z0, int z1);

// The bounds pyramid beside it (DESIGN.md "Virtual memory", "metadata is a min/max pyramid"): the least and the
// largest of the same 2³ voxels, so level l voxel v bounds every level-0 voxel below it, and with it
// every mean of them (each coarser level's values). NaN propagates: a NaN below makes the bound NaN,
// which block metadata reads as "anything".
void reduce_min(VoxelType t, const std::byte* src, ivec3 sd, std::byte* dst, int z0, int z1);
void reduce_max(VoxelType t, const std::byte* src, ivec3 sd, std::byte* dst, int z0, int z1);

// The label ids present below each voxel of a pyramid level >= 1 (labels bound like intensity: a
// coarse voxel's set holds every level-0 id below it, so the label mode of any level is in it). Each
// voxel holds the index of its set; sets are interned, since neighbouring voxels mostly share one.
struct LabelSetLevel {
  Volume sets;                            // u32 set index per voxel
  std::vector<std::uint32_t> offsets{0};  // set i is ids[offsets[i], offsets[i + 1]), ascending
  std::vector<std::uint32_t> ids;

  std::span<const std::uint32_t> set(std::uint32_t i) const {
    return {ids.data() + offsets[i], ids.data() + offsets[i + 1]};
  }
  std::size_t bytes() const;
};

// Level 1 from the level-0 label volume (integer type); level l + 1 from level l.
LabelSetLevel reduce_label_sets(const Volume& labels);
LabelSetLevel reduce_label_sets(const LabelSetLevel& finer);

// Fills a brick's (B + 2)³ stored voxels of `elem` bytes each: stored voxel s holds level voxel
// clamp(origin - 1 + s, 0, level_dims - 1), read from `src`, a dense array of dims src_dims holding
// level voxels [src_first, src_first + src_dims). src must cover every clamped voxel the brick needs.
void fill_brick(const BrickLayout& layout, BrickId id, const std::byte* src, ivec3 src_first, ivec3 src_dims,
                int elem, std::span<std::byte> out);

// The level-voxel box a brick reads, apron included, clamped to the level: [first, first + dims).
void brick_read_box(const BrickLayout& layout, BrickId id, ivec3& first, ivec3& dims);

}  // namespace sl
