// The `sharding_indexed` codec (array->bytes, the array's only codec): a shard of inner chunks, each
// encoded by the inner chain, and an index of (offset, nbytes) per inner chunk encoded by the index
// chain, at the shard's start or end. Reading it is v3_chunk.cpp's read_chunk.
#include <nlohmann/json.hpp>

#include "cache/formats/zarr/codecs/codec.h"
#include "cache/stores/byte_store.h"
#include "core/util/checked.h"

namespace sl::zarr::v3::codecs {
namespace {

using json = nlohmann::json;

// The inner chunk shape: one positive integer per axis, dividing the shard shape.
std::vector<std::int64_t> inner_shape(const json& config, const std::vector<std::int64_t>& chunk) {
  const std::size_t nd = chunk.size();
  if (!config.contains("chunk_shape") || !config["chunk_shape"].is_array() || config["chunk_shape"].size() != nd) {
    fail("sharding_indexed \"chunk_shape\" must list " + std::to_string(nd) + " integers");
  }
  std::vector<std::int64_t> inner;
  for (std::size_t i = 0; i < nd; ++i) {
    const json& v = config["chunk_shape"][i];
    if (!v.is_number_integer() || v.get<long long>() < 1 || chunk[i] % v.get<long long>() != 0) {
      fail("sharding_indexed chunk_shape " + config["chunk_shape"].dump() + " does not divide the shard shape " +
           shape_text(chunk));
    }
    inner.push_back(v.get<std::int64_t>());
  }
  return inner;
}

}  // namespace

std::string parse_sharding_indexed(const json& config, const ChainShape& shape, Chain&) {
  const std::vector<std::int64_t>& chunk = shape.chunk;
  const std::size_t nd = chunk.size();
  Sharding s;
  s.inner = inner_shape(config, chunk);
  s.inner_chain = parse_chain(config.contains("codecs") ? config["codecs"] : json(), s.inner, shape.elem, nullptr);
  // The index is an array of (offset, nbytes) uint64 pairs, one per inner chunk.
  std::vector<std::int64_t> ishape;
  for (std::size_t i = 0; i < nd; ++i) ishape.push_back(chunk[i] / s.inner[i]);
  ishape.push_back(2);
  s.index_chain = parse_chain(config.contains("index_codecs") ? config["index_codecs"] : json(), ishape, 8, nullptr);
  if (!s.index_chain.transpose.empty()) fail("a transposed shard index is not supported");
  // The index's encoded size follows from the whole chain; it must be fixed (no compressor).
  s.index_bytes = checked_mul(element_count(ishape), 8, "shard index bytes");
  for (const Chain::Step& st : s.index_chain.steps) {
    if (!st.crc32c) fail("shard index codecs must have a fixed size (bytes and crc32c only)");
    s.index_bytes = checked_add(s.index_bytes, 4, "shard index bytes");
  }
  // Read whole, before any inner chunk of the shard: bounded before it is ever allocated.
  checked_bound(s.index_bytes, kMaxIndexBytes + 64, "shard index");
  const std::string loc = config.value("index_location", std::string("end"));
  if (loc != "start" && loc != "end") fail("sharding_indexed index_location '" + loc + "' is not start or end");
  s.index_at_end = loc == "end";
  std::string text = "sharding_indexed (inner chunks " + shape_text(s.inner) + ": " + s.inner_chain.text + "; index at " +
                     loc + ": " + s.index_chain.text + ")";
  *shape.shard = std::move(s);
  return text;
}

}  // namespace sl::zarr::v3::codecs
