// The Zarr v3 shard (cache/formats/zarr/v3_chunk.cpp, sharding_indexed): the input is an array's
// zarr.json, a NUL byte, and the bytes of its first shard. The index (at the start or the end, through
// its own codecs, crc32c verified) is decoded and every inner chunk of the shard is read by its byte
// range and decoded: offsets and sizes past the object, overlapping or half-empty entries, corrupt
// inner chunks and checksums must all be refusals (std::runtime_error, which the reader turns into
// the InputError naming the store), never a read out of bounds.
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "cache/formats/zarr/array.h"
#include "cache/formats/zarr/v3_array.h"
#include "cache/formats/zarr/v3_chunk.h"
#include "cache/stores/byte_store.h"
#include "tests/fuzz/fuzz_util.h"

SL_FUZZ_TARGET(input) {
  const auto parts = sl::fuzz::split(input, std::string_view("\0", 1), 2);
  if (parts.size() < 2) return;
  const nlohmann::json j = nlohmann::json::parse(parts[0], nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded()) return;
  sl::zarr::ArrayMeta meta;
  try {
    meta = sl::zarr::v3::parse_array(j);
  } catch (const std::runtime_error&) {
    return;  // metadata the reader refuses (zarr3_store fuzzes that part)
  }
  const sl::zarr::v3::ArrayCodecs& a = *meta.v3;
  if (!a.shard || meta.chunk_bytes() > sl::fuzz::kMaxVolumeBytes) return;
  // The inner chunks of shard 0 that lie inside the array, slowest axis first.
  std::vector<std::int64_t> n(meta.shape.size());
  std::int64_t count = 1;
  for (std::size_t i = 0; i < n.size(); ++i) {
    const std::int64_t inner = a.shard->inner[i];
    n[i] = std::min((a.grid[i] + inner - 1) / inner, (meta.shape[i] + inner - 1) / inner);
    count *= n[i];
    if (count > 4096) return;  // a bound on the work per input, not a defect
  }
  const auto& dir = sl::fuzz::scratch().reset();
  const std::string shard_key = a.key(std::vector<std::int64_t>(n.size(), 0));
  sl::fuzz::write_file(dir / shard_key, parts[1]);
  const sl::LocalByteStore bytes(dir.string());
  sl::zarr::ChunkCache index_cache(sl::fuzz::kMaxVolumeBytes);
  std::vector<std::int64_t> c(n.size(), 0);
  for (std::int64_t k = 0; k < count; ++k) {
    for (std::size_t i = n.size(), r = std::size_t(k); i-- > 0; r /= std::size_t(n[i])) c[i] = std::int64_t(r % std::size_t(n[i]));
    try {
      const auto chunk = sl::zarr::v3::read_chunk(a, bytes, "", c, index_cache, "fuzz");
      if (chunk && chunk->size() != meta.chunk_bytes()) std::abort();  // a decoded chunk of the wrong size
    } catch (const std::runtime_error&) {
    }
  }
}
