// Reading one chunk of a Zarr v3 array's read grid through its codec chain (v3_codec.h). For a sharded
// array that grid is the inner chunks, each fetched alone by byte range from its shard (the shard index
// is read once and cached), so a brick reads only the inner chunks it overlaps.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "cache/formats/zarr/v3_codec.h"
#include "cache/stores/byte_store.h"

namespace sl::zarr {
class ChunkCache;
}

namespace sl::zarr::v3 {

// Reads and decodes chunk `c` of the read grid (one index per axis, slowest first: the inner chunks of
// a sharded array, the chunks otherwise) from `array_dir` (a key prefix of `bytes`, "" or ending in '/').
// Returns nullopt where nothing is stored (missing chunk or shard file, or an empty inner chunk):
// the fill value. Otherwise the chunk's voxels, C order, native byte order, int16 converted to float.
// Shard indices are cached in `cache` under `cache_prefix`. Throws std::runtime_error("chunk 'K': why"
// or "shard 'K' inner chunk I: why").
std::optional<std::vector<std::byte>> read_chunk(const ArrayCodecs& a, const ByteStore& bytes,
                                                 const std::string& array_dir, const std::vector<std::int64_t>& c,
                                                 ChunkCache& cache, const std::string& cache_prefix);

}  // namespace sl::zarr::v3
