// Zarr v3 codec chains (zarr.json "codecs"), reduced to what decoding needs: array->array `transpose`,
// array->bytes `bytes` (either endian) or `sharding_indexed`, bytes->bytes `gzip`, `zstd`, `blosc`
// (through compressor.h's decoders) and `crc32c` (verified: a mismatch is a corrupt chunk); one parser
// per codec in codecs/. Also the chunk key encodings (`default`: c/1/2/3, `v2`: 1.2.3). Reading a chunk
// through its chain is v3_chunk.h.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "cache/formats/zarr/compressor.h"

namespace sl::zarr::v3 {

// One codec chain, as zarr.json lists it, reduced to what decoding needs.
struct Chain {
  std::vector<int> transpose;  // encoded axis i is decoded axis transpose[i]; empty: identity
  bool big_endian = false;     // the `bytes` codec's endian
  struct Step {
    bool crc32c = false;       // otherwise `compressor`
    Compressor compressor;
  };
  std::vector<Step> steps;     // bytes->bytes codecs in encode order
  std::string text;            // "bytes (little), blosc (zstd, level 5, byte shuffle)"
};

struct Sharding {
  std::vector<std::int64_t> inner;  // inner chunk shape (slowest axis first); divides the shard shape
  Chain inner_chain, index_chain;
  bool index_at_end = true;
  std::uint64_t index_bytes = 0;    // encoded size of the index: 16 bytes per inner chunk through index_chain
};

// The stored element of a v3 array: what decoding produces before the conversion to the voxel type.
enum class Stored { U8, U16, U32, F32, I16 };
int stored_size(Stored s);

struct ArrayCodecs {
  Stored stored = Stored::U8;       // int16 decodes to float32 voxels (values kept), as NIfTI's do
  std::vector<std::int64_t> grid;   // the chunk_grid's chunk shape (the shard shape when sharded)
  bool default_keys = true;         // chunk_key_encoding `default` (prefix "c"), otherwise `v2`
  char separator = '/';
  Chain chain;                      // when not sharded
  std::optional<Sharding> shard;

  // Key of grid chunk `g` (one index per axis, slowest first), relative to the array directory.
  std::string key(const std::vector<std::int64_t>& g) const;
  std::string describe() const;     // for `info`
};

// Parses a "codecs" list for chunks of shape `chunk` (slowest axis first) of `elem`-byte elements.
// `shard` non-null accepts `sharding_indexed` (as the only codec) and fills it; null refuses it (nested
// sharding). Throws std::runtime_error with the reason for unknown codecs, bad configurations and
// chains this reader cannot decode (two compressors in one chain: the inner size is unknown).
Chain parse_chain(const nlohmann::json& codecs, const std::vector<std::int64_t>& chunk, int elem,
                  std::optional<Sharding>* shard);

// Castagnoli CRC-32 (the crc32c codec's checksum, RFC 3720).
std::uint32_t crc32c(const std::byte* p, std::size_t n);

}  // namespace sl::zarr::v3
