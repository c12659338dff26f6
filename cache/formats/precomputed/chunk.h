// Neuroglancer precomputed chunk encodings: `raw` (voxels x fastest, little-endian; gzip-wrapped as a
// whole file is accepted too, as CloudVolume writes it) and `compressed_segmentation` (neuroglancer's
// compressed_segmentation/README.md: per block a lookup table of ids and bit-packed indices into it),
// decoded to sparseleap voxels; uint64 narrows to u32 (an id past 2^32 - 1 is an error).
#pragma once

#include <cstddef>
#include <span>
#include <string>
#include <vector>

#include "cache/formats/precomputed/info.h"

namespace sl::precomputed {

// True when `b` starts with the gzip magic (1f 8b).
bool is_gzip(std::span<const std::byte> b);
// Inflates a gzip stream of unknown decoded size, refusing more than `max_out` bytes (a corrupt or
// hostile stream never allocates without bound). Throws std::runtime_error saying what is wrong.
std::vector<std::byte> gunzip(std::span<const std::byte> in, std::size_t max_out);

// Decodes chunk data of `shape` voxels (a chunk at the upper edge is clipped to the volume) stored with
// the scale's encoding into info.voxel_type() voxels, x fastest, native order. Throws
// std::runtime_error saying what is wrong (wrong size, bad offsets, an id too large).
std::vector<std::byte> decode_chunk(const Info& info, const Scale& s, std::span<const std::byte> data, ivec3 shape);

}  // namespace sl::precomputed
