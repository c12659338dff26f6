// What every chunked-store source (ZarrVolumeSource, PrecomputedVolumeSource) does with whole levels:
// read one in parallel chunk row by chunk row, derive the levels a store lacks below its coarsest one by
// the 2x reductions MemoryVolumeSource uses (pyramid.h: mean for intensity, mode for labels), and copy a
// clamped box out of a derived level for a brick.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "cache/brick.h"
#include "cache/pyramid.h"

#include "core/scene/volume.h"
#include "core/util/math.h"

namespace sl {

// Reads level voxels [first, first + n) (x fastest) into dst; throws InputError for a bad chunk.
using ReadBox = std::function<void(ivec3 first, ivec3 n, std::byte* dst)>;

// A whole level of dims/type/spacing `d` stored in chunks of `chunk` voxels, read chunk row by chunk row
// in parallel. With `skip_unreadable`, chunk by chunk instead, and a chunk whose read throws InputError
// is left 0 (a label scan that must not stop a render: the brick's own read reports it later).
Volume read_chunked_level(const VolumeDesc& d, ivec3 chunk, const ReadBox& read, const std::string& origin,
                          bool skip_unreadable = false);

// Copies level voxels [first, first + n), each coordinate clamped to the dims of `v`, into dst.
void copy_clamped(const Volume& v, ivec3 first, ivec3 n, std::byte* dst);

// Largest coarsest stored level that levels are derived from (in memory, at construction of a source).
inline constexpr std::uint64_t kMaxDerivedBaseBytes = std::uint64_t(512) << 20;

// Derived levels: 2x reductions of `base` by `reduce` (pyramid.h: reduce_mode for labels, the intensity
// pyramid's reduction otherwise) until 1³.
std::vector<Volume> derive_levels(const Volume& base, ReduceFn reduce);

// Reads level voxels [first, first + n) of a store's own level into dst (x fastest).
using ReadLevelBox = std::function<void(int level, ivec3 first, ivec3 n, std::byte* dst)>;

// One brick of a chunked store with `stored_levels` levels of voxel type `type`: its read box from the
// store's level through `read`, or beyond the stored levels from `derived` (derive_levels), written
// into `out` with the brick's apron (pyramid.h: brick_read_box, fill_brick).
void read_chunked_brick(const BrickLayout& layout, BrickId id, int stored_levels, VoxelType type,
                        const ReadLevelBox& read, const std::vector<Volume>& derived, std::span<std::byte> out);

}  // namespace sl
