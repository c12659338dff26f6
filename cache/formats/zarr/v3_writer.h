// Zarr v3 pieces of the store writer (writer.h, WriterOptions::zarr_format 3): an array's
// zarr.json (bytes little-endian + the compressor, optionally inside sharding_indexed with the index at
// the end as bytes + crc32c, as zarr-python writes it by default) and the assembly of one shard from its
// encoded inner chunks.
#pragma once

#include <cstddef>
#include <optional>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "cache/formats/zarr/compressor.h"
#include "core/scene/volume.h"
#include "core/util/math.h"

namespace sl::zarr::v3 {

// zarr.json of a 3-D (z, y, x) array of `dims` with chunk³ chunks, or with (chunk · shard)³ shards of
// chunk³ inner chunks when shard > 0; fill value 0. Throws std::runtime_error for a compressor that has
// no Zarr v3 codec (zlib).
nlohmann::json array_json(ivec3 dims, int chunk, int shard, VoxelType type, const Compressor& c);

// One shard file from its inner chunks in C order (z slowest; nullopt: not stored, an empty entry):
// the chunks back to back, then the index (offset, nbytes little-endian per chunk, 2^64-1 for empty)
// and its crc32c. Empty when no chunk is stored (the shard is then not written at all).
std::vector<std::byte> assemble_shard(const std::vector<std::optional<std::vector<std::byte>>>& chunks);

}  // namespace sl::zarr::v3
