// neuroglancer_uint64_sharded_v1 index decoding (cache/formats/precomputed/shard.cpp): byte 0 picks the
// sharding (bit 0: gzip minishard index; bit 1: murmurhash3_x86_128; bits 2-7: minishard_bits), bytes
// 1-16 are a shard index entry, the rest a stored minishard index. Both are decoded, and every chunk id
// the minishard index lists is located (hash, minishard, shard file name) as a read would.
#include <cstdint>
#include <span>
#include <stdexcept>

#include "cache/formats/precomputed/shard.h"
#include "tests/fuzz/fuzz_util.h"

SL_FUZZ_TARGET(input) {
  if (input.size() < 17) return;
  const auto* data = reinterpret_cast<const std::uint8_t*>(input.data());
  const std::size_t size = input.size();
  sl::precomputed::Sharding s;
  s.gzip_minishard_index = (data[0] & 1) != 0;
  s.murmur_hash = (data[0] & 2) != 0;
  s.minishard_bits = (data[0] >> 2) % 33;
  s.shard_bits = (data[0] >> 2) % 17;
  s.preshift_bits = data[1] % 65;
  const auto* b = reinterpret_cast<const std::byte*>(data);
  sl::precomputed::ByteRange r;
  try {
    r = sl::precomputed::decode_shard_index_entry(s, std::span(b + 1, 16));
    if (r.end < r.start || r.start < sl::precomputed::shard_index_bytes(s)) std::abort();  // decoder's promise
  } catch (const std::runtime_error&) {
  }
  try {
    for (const sl::precomputed::MinishardEntry& e : sl::precomputed::decode_minishard_index(s, std::span(b + 17, size - 17), r)) {
      if (e.offset < sl::precomputed::shard_index_bytes(s) || e.size > ~std::uint64_t(0) - e.offset) std::abort();
      const sl::precomputed::ShardLocation loc = sl::precomputed::locate_chunk(s, e.chunk_id);
      if (s.minishard_bits < 64 && loc.minishard >> s.minishard_bits) std::abort();
    }
  } catch (const std::runtime_error&) {
  }
}
