#include "cache/formats/precomputed/shard.h"

#include <bit>
#include <cstdio>
#include <cstring>
#include <stdexcept>

#include "cache/formats/precomputed/chunk.h"
#include "cache/stores/byte_store.h"

namespace sl::precomputed {
namespace {

std::uint32_t rotl32(std::uint32_t x, int r) { return (x << r) | (x >> (32 - r)); }

std::uint32_t fmix32(std::uint32_t h) {
  h ^= h >> 16;
  h *= 0x85ebca6bu;
  h ^= h >> 13;
  h *= 0xc2b2ae35u;
  h ^= h >> 16;
  return h;
}

std::uint64_t u64_at(std::span<const std::byte> b, std::size_t i) {
  std::uint64_t v;
  std::memcpy(&v, b.data() + i * 8, 8);
  return v;
}

// Largest minishard index accepted (byte_store.h's bound for any index read whole).
constexpr std::size_t kMaxMinishardIndexBytes = kMaxIndexBytes;

}  // namespace

std::uint64_t murmurhash3_x86_128_low64(std::uint64_t key) {
  // MurmurHash3_x86_128 (Austin Appleby, public domain) for an 8-byte input: no full 16-byte block, so
  // only the tail step runs, on k1 (bytes 0-3) and k2 (bytes 4-7).
  constexpr std::uint32_t c1 = 0x239b961bu, c2 = 0xab0e9789u, c3 = 0x38b34ae5u;
  std::uint32_t h1 = 0, h2 = 0, h3 = 0, h4 = 0;
  std::uint32_t k2 = std::uint32_t(key >> 32), k1 = std::uint32_t(key);
  k2 *= c2;
  k2 = rotl32(k2, 16);
  k2 *= c3;
  h2 ^= k2;
  k1 *= c1;
  k1 = rotl32(k1, 15);
  k1 *= c2;
  h1 ^= k1;
  h1 ^= 8u;
  h2 ^= 8u;
  h3 ^= 8u;
  h4 ^= 8u;
  h1 += h2 + h3 + h4;
  h2 += h1;
  h3 += h1;
  h4 += h1;
  h1 = fmix32(h1);
  h2 = fmix32(h2);
  h3 = fmix32(h3);
  h4 = fmix32(h4);
  h1 += h2 + h3 + h4;
  h2 += h1;
  return std::uint64_t(h1) | (std::uint64_t(h2) << 32);
}

std::uint64_t compressed_morton_code(ivec3 pos, ivec3 grid) {
  int bits[3];
  for (int d = 0; d < 3; ++d) bits[d] = int(std::bit_width(std::uint32_t(grid[d] - 1)));
  std::uint64_t code = 0;
  int j = 0;
  for (int i = 0; i < 32; ++i) {
    for (int d = 0; d < 3; ++d) {
      if (i < bits[d]) code |= std::uint64_t((std::uint32_t(pos[d]) >> i) & 1u) << j++;
    }
  }
  return code;
}

ShardLocation locate_chunk(const Sharding& s, std::uint64_t chunk_id) {
  std::uint64_t h = s.preshift_bits >= 64 ? 0 : chunk_id >> s.preshift_bits;
  if (s.murmur_hash) h = murmurhash3_x86_128_low64(h);
  const auto low = [](std::uint64_t v, int n) { return n >= 64 ? v : v & ((std::uint64_t(1) << n) - 1); };
  ShardLocation loc;
  loc.minishard = low(h, s.minishard_bits);
  const std::uint64_t shard = low(s.minishard_bits >= 64 ? 0 : h >> s.minishard_bits, s.shard_bits);
  char name[32];
  std::snprintf(name, sizeof name, "%0*llx.shard", (s.shard_bits + 3) / 4, (unsigned long long)shard);
  loc.file = name;
  return loc;
}

std::uint64_t shard_index_bytes(const Sharding& s) { return std::uint64_t(16) << s.minishard_bits; }

ByteRange decode_shard_index_entry(const Sharding& s, std::span<const std::byte> entry) {
  if (entry.size() != 16) throw std::runtime_error("shard index entry of " + std::to_string(entry.size()) + " bytes, not 16");
  const std::uint64_t a = u64_at(entry, 0), b = u64_at(entry, 1), base = shard_index_bytes(s);
  if (b < a) {
    throw std::runtime_error("shard index entry ends (" + std::to_string(b) + ") before it starts (" + std::to_string(a) + ")");
  }
  if (b > ~std::uint64_t(0) - base) throw std::runtime_error("shard index entry offset " + std::to_string(b) + " overflows");
  return {a + base, b + base};
}

std::vector<MinishardEntry> decode_minishard_index(const Sharding& s, std::span<const std::byte> stored, ByteRange where) {
  std::vector<std::byte> inflated;
  std::span<const std::byte> b = stored;
  if (s.gzip_minishard_index) {
    inflated = gunzip(stored, kMaxMinishardIndexBytes);
    b = inflated;
  }
  if (b.size() % 24 != 0) {
    throw std::runtime_error("minishard index of " + std::to_string(b.size()) + " bytes is not 24 bytes per chunk");
  }
  const std::size_t n = b.size() / 24;
  std::vector<MinishardEntry> out(n);
  const std::uint64_t base = shard_index_bytes(s), max = ~std::uint64_t(0);
  std::uint64_t id = 0, end = base;
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint64_t did = u64_at(b, i), doff = u64_at(b, n + i), size = u64_at(b, 2 * n + i);
    if (i > 0 && did == 0) throw std::runtime_error("minishard index lists chunk " + std::to_string(id) + " twice");
    if (did > max - id || doff > max - end || size > max - (end + doff)) {
      throw std::runtime_error("minishard index entry " + std::to_string(i) + " overflows 64 bits");
    }
    id += did;
    out[i] = {id, end + doff, size};
    if (size > 0 && out[i].offset < where.end && where.start < out[i].offset + size) {
      throw std::runtime_error("minishard index entry " + std::to_string(i) + " (bytes " + std::to_string(out[i].offset) + "+" +
                               std::to_string(size) + ") overlaps the minishard index itself (bytes " +
                               std::to_string(where.start) + "-" + std::to_string(where.end) + ")");
    }
    end += doff + size;
  }
  return out;
}

}  // namespace sl::precomputed
