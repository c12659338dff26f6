// neuroglancer_uint64_sharded_v1 (neuroglancer's precomputed/sharded.md): a volume chunk's id is the
// compressed Morton code of its grid position; id >> preshift_bits, hashed (identity or
// murmurhash3_x86_128), picks a minishard (low minishard_bits) and a shard (next shard_bits). A shard
// file begins with its index, 2^minishard_bits [start, end) pairs of uint64le locating each minishard
// index; a minishard index (raw or gzip) is 3n uint64le: the n chunk ids, delta coded, the n chunk
// offsets, each a delta from the end of the chunk before it, and the n sizes. All offsets count from the
// end of the shard index. Readers fetch one index entry, one minishard index and one chunk, each by byte
// range: never a whole shard.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "cache/formats/precomputed/info.h"

namespace sl::precomputed {

// MurmurHash3_x86_128 of the 8 little-endian bytes of `key` with seed 0; its low 64 bits.
std::uint64_t murmurhash3_x86_128_low64(std::uint64_t key);

// Compressed Morton code of chunk `pos` in a grid of `grid` chunks: bits of x, y, z interleaved from the
// least significant, each axis dropping out once its ceil(log2(grid)) bits are used.
std::uint64_t compressed_morton_code(ivec3 pos, ivec3 grid);

struct ShardLocation {
  std::string file;          // "1f.shard" (lower-case hex, ceil(shard_bits / 4) digits, at least one)
  std::uint64_t minishard;
};
ShardLocation locate_chunk(const Sharding& s, std::uint64_t chunk_id);

// Bytes of the shard index at the start of every shard file.
std::uint64_t shard_index_bytes(const Sharding& s);

// A shard index entry (16 bytes): the minishard index's byte range [start, end) in the shard file,
// absolute (the shard index size added). Throws std::runtime_error when end < start or it overflows.
struct ByteRange {
  std::uint64_t start = 0, end = 0;
};
ByteRange decode_shard_index_entry(const Sharding& s, std::span<const std::byte> entry);

struct MinishardEntry {
  std::uint64_t chunk_id, offset, size;  // offset absolute in the shard file
};
// Decodes a minishard index as stored at byte range `where` of its shard (gunzipping it when the sharding
// says so). Throws std::runtime_error when its length is not 24n bytes, an id repeats, an offset
// overflows (chunks that would overlap or lie past 2^64), or a chunk overlaps the index itself.
std::vector<MinishardEntry> decode_minishard_index(const Sharding& s, std::span<const std::byte> stored, ByteRange where);

}  // namespace sl::precomputed
