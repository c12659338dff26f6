// Zarr v2 chunk compressors (numcodecs ids zlib, gzip, zstd, blosc; or none), through the Debian
// libraries (zlib, libzstd, c-blosc). Used by the store reader (array.h), the writer (writer.h) and
// the v3 compressor codecs (codecs/). Every function here is thread-safe: blosc goes through its *_ctx
// entry points, which take no global lock and keep no global state.
#pragma once

#include <cstddef>
#include <span>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

namespace sl::zarr {

struct Compressor {
  enum class Id { None, Zlib, Gzip, Zstd, Blosc };
  Id id = Id::None;
  int level = 5;          // zlib/gzip 1-9, zstd 1-22, blosc clevel 0-9
  std::string cname;      // blosc inner codec: lz4, lz4hc, zstd, zlib, blosclz
  int shuffle = 1;        // blosc: 0 none, 1 byte, 2 bit (-1, numcodecs' AUTOSHUFFLE, is written as 1)
  int blocksize = 0;      // blosc: 0 = automatic
};

// Parses a .zarray "compressor" value (null or a numcodecs config). Throws std::runtime_error with
// the reason (the caller adds the store and array) for unknown ids or bad parameters.
Compressor parse_compressor(const nlohmann::json& j);
nlohmann::json to_json(const Compressor& c);
// "none", "zlib", "gzip", "zstd", "blosc-lz4", "blosc-zstd", "blosc-zlib" (the --compressor names),
// at `level` (none: the codec's default). Throws std::runtime_error for another name, for a level
// outside the codec's range and for a level given to "none" (the message starts with "level").
Compressor compressor_from_name(const std::string& name, std::optional<int> level = std::nullopt);
std::string describe(const Compressor& c);  // "blosc (zstd, level 5, byte shuffle)"

// Decodes one chunk, which must decode to exactly `out.size()` bytes. Throws std::runtime_error
// saying what is wrong (corrupt stream, truncated, wrong size) and nothing else for bad data.
void decode(const Compressor& c, std::span<const std::byte> in, std::span<std::byte> out);
// Encodes one chunk of items of `typesize` bytes (blosc shuffles by item).
std::vector<std::byte> encode(const Compressor& c, std::span<const std::byte> in, int typesize);

}  // namespace sl::zarr
