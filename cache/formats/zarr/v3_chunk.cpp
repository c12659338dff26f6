#include "cache/formats/zarr/v3_chunk.h"

#include <algorithm>
#include <bit>
#include <cstring>
#include <limits>
#include <stdexcept>

#include "cache/formats/zarr/chunk_cache.h"
#include "cache/formats/zarr/codecs/codec.h"
#include "core/util/error.h"

namespace sl::zarr::v3 {
namespace {

using codecs::fail;

constexpr std::uint64_t kEmpty = std::numeric_limits<std::uint64_t>::max();  // an empty inner chunk's offset and nbytes

void swap_bytes(std::byte* p, std::size_t count, int size) {
  for (std::size_t i = 0; i < count; ++i, p += size) std::reverse(p, p + size);
}

// Decodes one chain: the bytes->bytes steps in reverse, the byte order, then the inverse transpose.
// Returns the elements of `shape` in C order, native byte order.
std::vector<std::byte> decode_chain(const Chain& ch, std::vector<std::byte> in, const std::vector<std::int64_t>& shape,
                                    int elem) {
  const std::size_t n = codecs::element_count(shape), s0 = n * std::size_t(elem);
  for (std::size_t i = ch.steps.size(); i-- > 0;) {
    if (ch.steps[i].crc32c) {
      codecs::strip_crc32c(in);
    } else {
      // The compressor's input was s0 plus the checksums of the steps before it (parse_chain allows one
      // compressor, so every earlier step is a fixed-size crc32c).
      std::size_t size = s0;
      for (std::size_t k = 0; k < i; ++k) size += ch.steps[k].crc32c ? 4 : 0;
      std::vector<std::byte> out(size);
      decode(ch.steps[i].compressor, in, out);
      in = std::move(out);
    }
  }
  if (in.size() != s0) {
    fail("decodes to " + std::to_string(in.size()) + " bytes, expected " + std::to_string(s0) + " (" +
         codecs::shape_text(shape) + " elements of " + std::to_string(elem) + " bytes)");
  }
  if (elem > 1 && ch.big_endian != (std::endian::native == std::endian::big)) swap_bytes(in.data(), n, elem);
  if (ch.transpose.empty()) return in;
  return codecs::untranspose(in, ch.transpose, shape, elem);
}

std::string index_text(const std::vector<std::int64_t>& j) {
  std::string t = "(";
  for (std::size_t i = 0; i < j.size(); ++i) {
    if (i) t += ',';
    t += std::to_string(j[i]);
  }
  return t + ")";
}

// Decoded voxels from stored elements: int16 becomes float32 with its values; everything else is as stored.
std::vector<std::byte> to_voxels(Stored s, std::vector<std::byte> in) {
  if (s != Stored::I16) return in;
  const std::size_t n = in.size() / 2;
  std::vector<std::byte> out(n * 4);
  for (std::size_t i = 0; i < n; ++i) {
    std::int16_t v;
    std::memcpy(&v, in.data() + 2 * i, 2);
    const float f = float(v);
    std::memcpy(out.data() + 4 * i, &f, 4);
  }
  return out;
}

std::optional<std::vector<std::byte>> read_unsharded(const ArrayCodecs& a, const ByteStore& bytes,
                                                     const std::string& array_dir, const std::vector<std::int64_t>& c) {
  const std::string key = a.key(c);
  try {
    std::optional<std::vector<std::byte>> raw = bytes.read(array_dir + key, kMaxChunkObjectBytes);
    if (!raw) return std::nullopt;
    return to_voxels(a.stored, decode_chain(a.chain, std::move(*raw), a.grid, stored_size(a.stored)));
  } catch (const TransientError& e) {
    throw TransientError("", "chunk '" + key + "': " + e.what());  // still retriable (core/util/error.h)
  } catch (const std::runtime_error& e) {
    fail("chunk '" + key + "': " + e.what());
  }
}

// The decoded index of shard `key` (`inner_per_axis` inner chunks along each axis), through `cache`. A
// missing shard is remembered as an empty index: every inner chunk reads as the fill value.
ChunkCache::Chunk shard_index(const Sharding& sh, const ByteStore& bytes, const std::string& object,
                              const std::vector<std::int64_t>& inner_per_axis, ChunkCache& cache,
                              const std::string& cache_key) {
  if (ChunkCache::Chunk index = cache.get(cache_key)) return index;
  std::optional<std::vector<std::byte>> raw =
      sh.index_at_end ? bytes.read_suffix(object, sh.index_bytes) : bytes.read_range(object, 0, sh.index_bytes);
  std::vector<std::int64_t> ishape = inner_per_axis;
  ishape.push_back(2);
  auto decoded = std::make_shared<std::vector<std::byte>>();
  if (raw) {
    try {
      *decoded = decode_chain(sh.index_chain, std::move(*raw), ishape, 8);
    } catch (const std::runtime_error& e) {
      throw std::runtime_error(std::string("shard index ") + e.what());
    }
  }
  ChunkCache::Chunk index = std::move(decoded);
  cache.put(cache_key, index);
  return index;
}

// Inner chunk `c` of the read grid: its shard's index entry, then its bytes by range.
std::optional<std::vector<std::byte>> read_inner_chunk(const ArrayCodecs& a, const ByteStore& bytes,
                                                       const std::string& array_dir, const std::vector<std::int64_t>& c,
                                                       ChunkCache& cache, const std::string& cache_prefix) {
  const Sharding& sh = *a.shard;
  const std::size_t nd = c.size();
  std::vector<std::int64_t> s(nd), j(nd), cps(nd);  // shard, inner chunk within it, inner chunks per shard
  std::size_t inner_index = 0;
  for (std::size_t i = 0; i < nd; ++i) {
    cps[i] = a.grid[i] / sh.inner[i];
    s[i] = c[i] / cps[i];
    j[i] = c[i] % cps[i];
    inner_index = inner_index * std::size_t(cps[i]) + std::size_t(j[i]);
  }
  const std::string key = a.key(s);
  const auto where = [&] { return "shard '" + key + "' inner chunk " + index_text(j) + ": "; };
  try {
    const ChunkCache::Chunk index = shard_index(sh, bytes, array_dir + key, cps, cache, cache_prefix + "#index:" + key);
    if (index->empty()) return std::nullopt;
    std::uint64_t off = 0, n = 0;
    std::memcpy(&off, index->data() + inner_index * 16, 8);
    std::memcpy(&n, index->data() + inner_index * 16 + 8, 8);
    if (off == kEmpty && n == kEmpty) return std::nullopt;
    if (off == kEmpty || n == kEmpty || n > kEmpty - off) {
      fail("shard index entry (offset " + std::to_string(off) + ", nbytes " + std::to_string(n) + ") is malformed");
    }
    std::optional<std::vector<std::byte>> raw = bytes.read_range(array_dir + key, off, n);
    if (!raw) return std::nullopt;  // the shard vanished after its index was read
    return to_voxels(a.stored, decode_chain(sh.inner_chain, std::move(*raw), sh.inner, stored_size(a.stored)));
  } catch (const TransientError& e) {
    throw TransientError("", where() + e.what());
  } catch (const std::runtime_error& e) {
    fail(where() + e.what());
  }
}

}  // namespace

std::optional<std::vector<std::byte>> read_chunk(const ArrayCodecs& a, const ByteStore& bytes, const std::string& array_dir,
                                                 const std::vector<std::int64_t>& c, ChunkCache& cache,
                                                 const std::string& cache_prefix) {
  if (!a.shard) return read_unsharded(a, bytes, array_dir, c);
  return read_inner_chunk(a, bytes, array_dir, c, cache, cache_prefix);
}

}  // namespace sl::zarr::v3
