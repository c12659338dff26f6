// The Zarr v3 codecs this reader decodes, one parser each (a file per codec in this folder), found by
// name in one table (codec.cpp). parse_chain (v3_codec.cpp) looks a codec up, checks that it stands
// where its role allows, and lets its parser fill the chain; the parsers check only their configuration.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "cache/formats/zarr/v3_codec.h"

namespace sl::zarr::v3::codecs {

// Where a codec may stand in a chain (the Zarr v3 codec kinds): array->array codecs first, then exactly
// one array->bytes codec, then bytes->bytes codecs. sharding_indexed is array->bytes but must be the
// array's only codec (its inner chain holds the others). At most one bytes->bytes codec compresses:
// decoding sizes the compressor's output from the fixed-size checksums encoded before it.
enum class Role { ArrayToArray, ArrayToBytes, Sharding, Compressor, Checksum };

// What a parser knows of the chain it is part of.
struct ChainShape {
  const std::vector<std::int64_t>& chunk;  // decoded chunk shape, slowest axis first
  int elem;                                // bytes per decoded element
  std::optional<Sharding>* shard;          // where sharding_indexed puts the shard's layout
};

// Parses one codec's configuration (an empty object when the codec has none) into `chain` and returns
// its part of Chain::text ("bytes (little)"). Throws std::runtime_error with the reason.
using Parse = std::string (*)(const nlohmann::json& config, const ChainShape& shape, Chain& chain);

struct Codec {
  std::string_view name;
  Role role;
  Parse parse;
};

// Every codec, in the order the "not supported" message lists them.
std::span<const Codec> all();
// The codec named `name`; null for one this reader does not decode.
const Codec* find(std::string_view name);

std::string parse_transpose(const nlohmann::json& config, const ChainShape& shape, Chain& chain);
std::string parse_bytes(const nlohmann::json& config, const ChainShape& shape, Chain& chain);
std::string parse_sharding_indexed(const nlohmann::json& config, const ChainShape& shape, Chain& chain);
std::string parse_gzip(const nlohmann::json& config, const ChainShape& shape, Chain& chain);
std::string parse_zstd(const nlohmann::json& config, const ChainShape& shape, Chain& chain);
std::string parse_blosc(const nlohmann::json& config, const ChainShape& shape, Chain& chain);
std::string parse_crc32c(const nlohmann::json& config, const ChainShape& shape, Chain& chain);

// Decoding steps that belong to one codec.
// transpose: the elements of `in` (of `elem` bytes, in the encoded axis order) placed in decoded C order
// of `shape`; encoded axis i is decoded axis order[i].
std::vector<std::byte> untranspose(const std::vector<std::byte>& in, const std::vector<int>& order,
                                   const std::vector<std::int64_t>& shape, int elem);
// crc32c: checks the checksum at the end of `in` and removes it; a mismatch is a corrupt chunk.
void strip_crc32c(std::vector<std::byte>& in);

// Shared by the parsers and the decoder.
[[noreturn]] void fail(const std::string& why);
// The integer `key` of a codec's configuration, `def` when absent; fails naming `codec` unless in [lo, hi].
int int_config(const nlohmann::json& config, const char* key, int def, int lo, int hi, const std::string& codec);
// "32x32x32" for messages.
std::string shape_text(const std::vector<std::int64_t>& shape);
// Elements in `shape`.
std::size_t element_count(const std::vector<std::int64_t>& shape);

}  // namespace sl::zarr::v3::codecs
