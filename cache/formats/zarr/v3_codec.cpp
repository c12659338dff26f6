#include "cache/formats/zarr/v3_codec.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cstring>
#include <limits>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "cache/formats/zarr/array.h"
#include "core/util/error.h"

namespace sl::zarr::v3 {
namespace {

using json = nlohmann::json;

[[noreturn]] void fail(const std::string& why) { throw std::runtime_error(why); }

constexpr std::uint64_t kEmpty = std::numeric_limits<std::uint64_t>::max();  // an empty inner chunk's offset and nbytes

std::string shape_text(const std::vector<std::int64_t>& s) {
  std::string t;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (i) t += 'x';
    t += std::to_string(s[i]);
  }
  return t;
}

const json& config(const json& codec) {
  static const json kEmptyObject = json::object();
  if (!codec.contains("configuration")) return kEmptyObject;
  if (!codec["configuration"].is_object()) fail("codec configuration must be an object");
  return codec["configuration"];
}

int int_config(const json& cfg, const char* key, int def, int lo, int hi, const std::string& codec) {
  if (!cfg.contains(key)) return def;
  if (!cfg[key].is_number_integer() || cfg[key].get<long long>() < lo || cfg[key].get<long long>() > hi) {
    fail(codec + " configuration '" + key + "' must be an integer in " + std::to_string(lo) + ".." + std::to_string(hi));
  }
  return cfg[key].get<int>();
}

Compressor blosc_of(const json& cfg) {
  Compressor c;
  c.id = Compressor::Id::Blosc;
  c.cname = cfg.value("cname", std::string("zstd"));
  if (c.cname != "lz4" && c.cname != "lz4hc" && c.cname != "zstd" && c.cname != "zlib" && c.cname != "blosclz") {
    fail("blosc cname '" + c.cname + "' is not supported (lz4, lz4hc, zstd, zlib, blosclz)");
  }
  c.level = int_config(cfg, "clevel", 5, 0, 9, "blosc");
  const std::string sh = cfg.contains("shuffle") && cfg["shuffle"].is_string() ? cfg["shuffle"].get<std::string>() : "noshuffle";
  if (sh == "noshuffle") c.shuffle = 0;
  else if (sh == "shuffle") c.shuffle = 1;
  else if (sh == "bitshuffle") c.shuffle = 2;
  else fail("blosc shuffle '" + sh + "' is not one of noshuffle, shuffle, bitshuffle");
  c.blocksize = int_config(cfg, "blocksize", 0, 0, std::numeric_limits<int>::max(), "blosc");
  return c;
}

void swap_bytes(std::byte* p, std::size_t count, int size) {
  for (std::size_t i = 0; i < count; ++i, p += size) std::reverse(p, p + size);
}

std::size_t count(const std::vector<std::int64_t>& shape) {
  std::size_t n = 1;
  for (std::int64_t s : shape) n *= std::size_t(s);
  return n;
}

// Decodes one chain: the bytes->bytes steps in reverse, the byte order, then the inverse transpose.
// Returns the elements of `shape` in C order, native byte order.
std::vector<std::byte> decode_chain(const Chain& ch, std::vector<std::byte> in, const std::vector<std::int64_t>& shape,
                                    int elem) {
  const std::size_t n = count(shape), s0 = n * std::size_t(elem);
  for (std::size_t i = ch.steps.size(); i-- > 0;) {
    if (ch.steps[i].crc32c) {
      if (in.size() < 4) fail("too short (" + std::to_string(in.size()) + " bytes) for its crc32c checksum");
      std::uint32_t stored = 0;
      for (int b = 3; b >= 0; --b) stored = (stored << 8) | std::uint32_t(in[in.size() - 4 + std::size_t(b)]);
      const std::uint32_t got = crc32c(in.data(), in.size() - 4);
      if (got != stored) {
        fail("crc32c checksum mismatch (stored " + std::to_string(stored) + ", computed " + std::to_string(got) +
             "): the chunk is corrupt");
      }
      in.resize(in.size() - 4);
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
         shape_text(shape) + " elements of " + std::to_string(elem) + " bytes)");
  }
  if (elem > 1 && ch.big_endian != (std::endian::native == std::endian::big)) swap_bytes(in.data(), n, elem);
  if (ch.transpose.empty()) return in;
  // Encoded axis i is decoded axis t[i]: walk the encoded array in C order, placing each element at its
  // decoded offset.
  const std::size_t nd = shape.size();
  std::vector<std::size_t> dstride(nd, 1), step(nd), es(nd), e(nd, 0);
  for (std::size_t i = nd - 1; i-- > 0;) dstride[i] = dstride[i + 1] * std::size_t(shape[i + 1]);
  for (std::size_t i = 0; i < nd; ++i) {
    es[i] = std::size_t(shape[std::size_t(ch.transpose[i])]);
    step[i] = dstride[std::size_t(ch.transpose[i])];
  }
  std::vector<std::byte> out(in.size());
  std::size_t off = 0;
  for (std::size_t k = 0; k < n; ++k) {
    std::memcpy(out.data() + off * std::size_t(elem), in.data() + k * std::size_t(elem), std::size_t(elem));
    for (std::size_t i = nd; i-- > 0;) {
      off += step[i];
      if (++e[i] < es[i]) break;
      off -= step[i] * es[i];
      e[i] = 0;
    }
  }
  return out;
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

}  // namespace

int stored_size(Stored s) {
  switch (s) {
    case Stored::U8: return 1;
    case Stored::U16: case Stored::I16: return 2;
    case Stored::U32: case Stored::F32: return 4;
  }
  return 1;
}

std::uint32_t crc32c(const std::byte* p, std::size_t n) {
  static const std::array<std::uint32_t, 256> kTable = [] {
    std::array<std::uint32_t, 256> t{};
    for (std::uint32_t i = 0; i < 256; ++i) {
      std::uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = (c & 1) ? (c >> 1) ^ 0x82F63B78u : c >> 1;  // reflected Castagnoli polynomial
      t[i] = c;
    }
    return t;
  }();
  std::uint32_t c = 0xFFFFFFFFu;
  for (std::size_t i = 0; i < n; ++i) c = kTable[(c ^ std::uint32_t(p[i])) & 0xFFu] ^ (c >> 8);
  return c ^ 0xFFFFFFFFu;
}

Chain parse_chain(const json& codecs, const std::vector<std::int64_t>& chunk, int elem, std::optional<Sharding>* shard) {
  if (!codecs.is_array() || codecs.empty()) fail("\"codecs\" must be a non-empty list");
  Chain ch;
  const std::size_t nd = chunk.size();
  bool have_bytes = false, have_compressor = false;
  std::vector<std::string> parts;
  for (const json& c : codecs) {
    if (!c.is_object() || !c.contains("name") || !c["name"].is_string()) fail("every codec needs a string \"name\"");
    const std::string name = c["name"].get<std::string>();
    const json& cfg = config(c);
    if (name == "transpose") {
      if (have_bytes) fail("transpose after the array->bytes codec");
      if (!cfg.contains("order") || !cfg["order"].is_array() || cfg["order"].size() != nd) {
        fail("transpose \"order\" must list " + std::to_string(nd) + " axes");
      }
      std::vector<int> t;
      std::vector<bool> seen(nd, false);
      for (const json& o : cfg["order"]) {
        if (!o.is_number_integer() || o.get<long long>() < 0 || o.get<long long>() >= (long long)nd ||
            seen[o.get<std::size_t>()]) {
          fail("transpose \"order\" must be a permutation of 0.." + std::to_string(nd - 1));
        }
        seen[o.get<std::size_t>()] = true;
        t.push_back(o.get<int>());
      }
      // Two transposes compose: encoded axis j of the second is decoded axis first[second[j]].
      if (!ch.transpose.empty()) {
        for (int& a : t) a = ch.transpose[std::size_t(a)];
      }
      ch.transpose = t;
      parts.push_back("transpose");
    } else if (name == "bytes") {
      if (have_bytes) fail("two array->bytes codecs");
      have_bytes = true;
      const std::string endian = cfg.contains("endian") && cfg["endian"].is_string() ? cfg["endian"].get<std::string>() : "";
      if (endian.empty() && elem > 1) fail("bytes codec needs an \"endian\" for multi-byte data");
      if (!endian.empty() && endian != "little" && endian != "big") fail("bytes endian '" + endian + "' is not little or big");
      ch.big_endian = endian == "big";
      parts.push_back(elem > 1 ? "bytes (" + endian + ")" : "bytes");
    } else if (name == "sharding_indexed") {
      if (!shard) fail("nested sharding_indexed is not supported");
      if (codecs.size() != 1) fail("sharding_indexed must be the only codec of the array (others go inside the shard)");
      Sharding s;
      std::optional<Sharding> none;
      std::vector<std::int64_t> inner;
      if (!cfg.contains("chunk_shape") || !cfg["chunk_shape"].is_array() || cfg["chunk_shape"].size() != nd) {
        fail("sharding_indexed \"chunk_shape\" must list " + std::to_string(nd) + " integers");
      }
      for (std::size_t i = 0; i < nd; ++i) {
        const json& v = cfg["chunk_shape"][i];
        if (!v.is_number_integer() || v.get<long long>() < 1 || chunk[i] % v.get<long long>() != 0) {
          fail("sharding_indexed chunk_shape " + cfg["chunk_shape"].dump() + " does not divide the shard shape " +
               shape_text(chunk));
        }
        inner.push_back(v.get<std::int64_t>());
      }
      s.inner = inner;
      s.inner_chain = parse_chain(cfg.contains("codecs") ? cfg["codecs"] : json(), inner, elem, nullptr);
      std::vector<std::int64_t> ishape;
      for (std::size_t i = 0; i < nd; ++i) ishape.push_back(chunk[i] / inner[i]);
      ishape.push_back(2);
      s.index_chain = parse_chain(cfg.contains("index_codecs") ? cfg["index_codecs"] : json(), ishape, 8, nullptr);
      if (!s.index_chain.transpose.empty()) fail("a transposed shard index is not supported");
      // The index's encoded size follows from the whole chain; it must be fixed (no compressor).
      s.index_bytes = count(ishape) * 8;
      for (const Chain::Step& st : s.index_chain.steps) {
        if (!st.crc32c) fail("shard index codecs must have a fixed size (bytes and crc32c only)");
        s.index_bytes += 4;
      }
      const std::string loc = cfg.value("index_location", std::string("end"));
      if (loc != "start" && loc != "end") fail("sharding_indexed index_location '" + loc + "' is not start or end");
      s.index_at_end = loc == "end";
      ch.text = "sharding_indexed (inner chunks " + shape_text(inner) + ": " + s.inner_chain.text + "; index at " + loc +
                ": " + s.index_chain.text + ")";
      *shard = std::move(s);
      return ch;
    } else if (name == "crc32c") {
      if (!have_bytes) fail("crc32c before the array->bytes codec");
      ch.steps.push_back({true, {}});
      parts.push_back("crc32c");
    } else if (name == "gzip" || name == "zstd" || name == "blosc") {
      if (!have_bytes) fail(name + " before the array->bytes codec");
      if (have_compressor) fail("two compressors in one chain are not supported");
      have_compressor = true;
      Compressor k;
      if (name == "gzip") {
        k.id = Compressor::Id::Gzip;
        k.level = int_config(cfg, "level", 5, 0, 9, name);
      } else if (name == "zstd") {
        k.id = Compressor::Id::Zstd;
        k.level = int_config(cfg, "level", 0, -131072, 22, name);
      } else {
        k = blosc_of(cfg);
      }
      ch.steps.push_back({false, k});
      parts.push_back(zarr::describe(k));
    } else {
      fail("codec '" + name + "' is not supported (transpose, bytes, sharding_indexed, gzip, zstd, blosc, crc32c)");
    }
  }
  if (!have_bytes) fail("no array->bytes codec (bytes or sharding_indexed)");
  for (std::size_t i = 0; i < parts.size(); ++i) {
    if (i) ch.text += ", ";
    ch.text += parts[i];
  }
  return ch;
}

std::string ArrayCodecs::key(const std::vector<std::int64_t>& g) const {
  std::string k = default_keys ? "c" : "";
  for (std::size_t i = 0; i < g.size(); ++i) {
    if (i > 0 || default_keys) k += separator;
    k += std::to_string(g[i]);
  }
  if (!default_keys && g.empty()) k = "0";
  return k;
}

std::string ArrayCodecs::describe() const {
  return (shard ? "shards " + shape_text(grid) + ", " : std::string()) + chain.text + ", keys " +
         (default_keys ? "default" : "v2") + " '" + separator + "'";
}

std::optional<std::vector<std::byte>> read_chunk(const ArrayCodecs& a, const ByteStore& bytes, const std::string& array_dir,
                                                 const std::vector<std::int64_t>& c, ChunkCache& cache,
                                                 const std::string& cache_prefix) {
  const int elem = stored_size(a.stored);
  if (!a.shard) {
    const std::string key = a.key(c);
    try {
      std::optional<std::vector<std::byte>> raw = bytes.read(array_dir + key);
      if (!raw) return std::nullopt;
      return to_voxels(a.stored, decode_chain(a.chain, std::move(*raw), a.grid, elem));
    } catch (const TransientError& e) {
      throw TransientError("", "chunk '" + key + "': " + e.what());  // still retriable (core/util/error.h)
    } catch (const std::runtime_error& e) {
      fail("chunk '" + key + "': " + e.what());
    }
  }
  const Sharding& sh = *a.shard;
  const std::size_t nd = c.size();
  std::vector<std::int64_t> s(nd), j(nd), cps(nd);
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
    const std::string ikey = cache_prefix + "#index:" + key;
    ChunkCache::Chunk index = cache.get(ikey);
    if (!index) {
      std::optional<std::vector<std::byte>> raw =
          sh.index_at_end ? bytes.read_suffix(array_dir + key, sh.index_bytes) : bytes.read_range(array_dir + key, 0, sh.index_bytes);
      std::vector<std::int64_t> ishape = cps;
      ishape.push_back(2);
      // A missing shard is remembered as an empty index: every inner chunk reads as the fill value.
      auto decoded = std::make_shared<std::vector<std::byte>>();
      if (raw) {
        try {
          *decoded = decode_chain(sh.index_chain, std::move(*raw), ishape, 8);
        } catch (const std::runtime_error& e) {
          throw std::runtime_error(std::string("shard index ") + e.what());
        }
      }
      index = std::move(decoded);
      cache.put(ikey, index);
    }
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
    return to_voxels(a.stored, decode_chain(sh.inner_chain, std::move(*raw), sh.inner, elem));
  } catch (const TransientError& e) {
    throw TransientError("", where() + e.what());
  } catch (const std::runtime_error& e) {
    fail(where() + e.what());
  }
}

}  // namespace sl::zarr::v3
