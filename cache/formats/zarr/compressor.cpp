#include "cache/formats/zarr/compressor.h"

#include <blosc.h>
#include <zlib.h>
#include <zstd.h>

#include <cstring>
#include <limits>
#include <new>
#include <nlohmann/json.hpp>
#include <stdexcept>

namespace sl::zarr {
namespace {

using json = nlohmann::json;

[[noreturn]] void fail(const std::string& why) { throw std::runtime_error(why); }

std::string size_text(std::size_t n) { return std::to_string(n) + " bytes"; }

int int_field(const json& j, const char* key, int def, int lo, int hi) {
  if (!j.contains(key) || j[key].is_null()) return def;
  if (!j[key].is_number_integer()) fail(std::string("compressor field '") + key + "' must be an integer");
  const auto v = j[key].get<long long>();
  if (v < lo || v > hi) {
    fail(std::string("compressor field '") + key + "' = " + std::to_string(v) + " is outside " +
         std::to_string(lo) + ".." + std::to_string(hi));
  }
  return int(v);
}

// zlib and gzip chunks: inflate with automatic header detection (15 + 32), so either wrapper works.
void inflate_chunk(std::span<const std::byte> in, std::span<std::byte> out, const char* what) {
  if (in.size() > std::numeric_limits<uInt>::max() || out.size() > std::numeric_limits<uInt>::max()) {
    fail(std::string(what) + " chunk too large");
  }
  z_stream zs{};
  if (inflateInit2(&zs, 15 + 32) != Z_OK) throw std::bad_alloc();
  zs.next_in = reinterpret_cast<Bytef*>(const_cast<std::byte*>(in.data()));
  zs.avail_in = uInt(in.size());
  zs.next_out = reinterpret_cast<Bytef*>(out.data());
  zs.avail_out = uInt(out.size());
  int ret = inflate(&zs, Z_FINISH);
  const std::size_t got = out.size() - zs.avail_out;
  std::string msg = zs.msg ? zs.msg : "";
  // Anything left after the output is full means the chunk decodes to more than expected.
  unsigned char extra = 0;
  if (ret == Z_BUF_ERROR && zs.avail_out == 0 && zs.avail_in > 0) {
    zs.next_out = &extra;
    zs.avail_out = 1;
    ret = inflate(&zs, Z_FINISH);
    if (zs.avail_out == 0) {
      inflateEnd(&zs);
      fail(std::string(what) + " chunk decompresses to more than the expected " + size_text(out.size()));
    }
  }
  inflateEnd(&zs);
  if (ret == Z_STREAM_END) {
    if (got != out.size()) {
      fail(std::string(what) + " chunk decompresses to " + size_text(got) + ", expected " + size_text(out.size()));
    }
    return;
  }
  if (ret == Z_DATA_ERROR || ret == Z_NEED_DICT || ret == Z_STREAM_ERROR) {
    fail(std::string(what) + " chunk is corrupt (zlib: " + (msg.empty() ? "invalid stream" : msg) + ")");
  }
  if (ret == Z_MEM_ERROR) throw std::bad_alloc();
  fail(std::string(what) + " chunk is truncated (stream ends after " + size_text(got) + " of " +
       size_text(out.size()) + ")");
}

std::vector<std::byte> deflate_chunk(std::span<const std::byte> in, int level, bool gzip) {
  z_stream zs{};
  if (deflateInit2(&zs, level, Z_DEFLATED, gzip ? 15 + 16 : 15, 8, Z_DEFAULT_STRATEGY) != Z_OK) {
    throw std::bad_alloc();
  }
  std::vector<std::byte> out(deflateBound(&zs, uLong(in.size())) + 32);
  zs.next_in = reinterpret_cast<Bytef*>(const_cast<std::byte*>(in.data()));
  zs.avail_in = uInt(in.size());
  zs.next_out = reinterpret_cast<Bytef*>(out.data());
  zs.avail_out = uInt(out.size());
  const int ret = deflate(&zs, Z_FINISH);
  out.resize(out.size() - zs.avail_out);
  deflateEnd(&zs);
  if (ret != Z_STREAM_END) throw std::logic_error("deflate did not finish in one call");
  return out;
}

}  // namespace

Compressor parse_compressor(const json& j) {
  Compressor c;
  if (j.is_null()) return c;
  if (!j.is_object() || !j.contains("id") || !j["id"].is_string()) {
    fail("compressor must be null or an object with a string \"id\"");
  }
  const std::string id = j["id"].get<std::string>();
  if (id == "zlib" || id == "gzip") {
    c.id = id == "zlib" ? Compressor::Id::Zlib : Compressor::Id::Gzip;
    c.level = int_field(j, "level", 1, 0, 9);
  } else if (id == "zstd") {
    c.id = Compressor::Id::Zstd;
    c.level = int_field(j, "level", 1, -131072, 22);
  } else if (id == "blosc") {
    c.id = Compressor::Id::Blosc;
    c.level = int_field(j, "clevel", 5, 0, 9);
    c.shuffle = int_field(j, "shuffle", 1, -1, 2);
    if (c.shuffle == -1) c.shuffle = 1;
    c.blocksize = int_field(j, "blocksize", 0, 0, std::numeric_limits<int>::max());
    c.cname = j.contains("cname") && j["cname"].is_string() ? j["cname"].get<std::string>() : "lz4";
    if (c.cname != "lz4" && c.cname != "lz4hc" && c.cname != "zstd" && c.cname != "zlib" && c.cname != "blosclz") {
      fail("blosc inner codec '" + c.cname + "' is not supported (lz4, lz4hc, zstd, zlib, blosclz)");
    }
  } else {
    fail("unknown compressor id '" + id + "' (supported: null, zlib, gzip, zstd, blosc)");
  }
  return c;
}

json to_json(const Compressor& c) {
  switch (c.id) {
    case Compressor::Id::None: return nullptr;
    case Compressor::Id::Zlib: return {{"id", "zlib"}, {"level", c.level}};
    case Compressor::Id::Gzip: return {{"id", "gzip"}, {"level", c.level}};
    case Compressor::Id::Zstd: return {{"id", "zstd"}, {"level", c.level}};
    case Compressor::Id::Blosc:
      return {{"id", "blosc"}, {"cname", c.cname}, {"clevel", c.level}, {"shuffle", c.shuffle},
              {"blocksize", c.blocksize}};
  }
  return nullptr;
}

Compressor compressor_from_name(const std::string& name, std::optional<int> level) {
  Compressor c;
  // Each codec's documented range; a level outside it is refused, never clamped or replaced.
  const auto at = [&](int fallback, int hi) {
    if (level && (*level < 0 || *level > hi)) {
      fail("level must be 0-" + std::to_string(hi) + " for " + name + ", got " + std::to_string(*level));
    }
    c.level = level ? *level : fallback;
  };
  if (name == "none") {
    if (level) fail("level: the compressor none takes no level");
    return c;
  } else if (name == "zlib" || name == "gzip") {
    c.id = name == "zlib" ? Compressor::Id::Zlib : Compressor::Id::Gzip;
    at(6, 9);
  } else if (name == "zstd") {
    c.id = Compressor::Id::Zstd;
    at(3, 22);
  } else if (name == "blosc-lz4" || name == "blosc-zstd" || name == "blosc-zlib") {
    c.id = Compressor::Id::Blosc;
    c.cname = name.substr(6);
    at(5, 9);
  } else {
    fail("unknown compressor '" + name + "' (none, zlib, gzip, zstd, blosc-lz4, blosc-zstd, blosc-zlib)");
  }
  return c;
}

std::string describe(const Compressor& c) {
  switch (c.id) {
    case Compressor::Id::None: return "none";
    case Compressor::Id::Zlib: return "zlib (level " + std::to_string(c.level) + ")";
    case Compressor::Id::Gzip: return "gzip (level " + std::to_string(c.level) + ")";
    case Compressor::Id::Zstd: return "zstd (level " + std::to_string(c.level) + ")";
    case Compressor::Id::Blosc:
      return "blosc (" + c.cname + ", level " + std::to_string(c.level) + ", " +
             (c.shuffle == 0 ? "no shuffle" : c.shuffle == 1 ? "byte shuffle" : "bit shuffle") + ")";
  }
  return "?";
}

void decode(const Compressor& c, std::span<const std::byte> in, std::span<std::byte> out) {
  switch (c.id) {
    case Compressor::Id::None:
      if (in.size() != out.size()) {
        fail("uncompressed chunk has " + size_text(in.size()) + ", expected " + size_text(out.size()));
      }
      std::memcpy(out.data(), in.data(), out.size());
      return;
    case Compressor::Id::Zlib: inflate_chunk(in, out, "zlib"); return;
    case Compressor::Id::Gzip: inflate_chunk(in, out, "gzip"); return;
    case Compressor::Id::Zstd: {
      const unsigned long long n = ZSTD_getFrameContentSize(in.data(), in.size());
      if (n == ZSTD_CONTENTSIZE_ERROR) fail("zstd chunk is corrupt (not a zstd frame)");
      if (n != ZSTD_CONTENTSIZE_UNKNOWN && n != out.size()) {
        fail("zstd chunk decompresses to " + size_text(std::size_t(n)) + ", expected " + size_text(out.size()));
      }
      const std::size_t r = ZSTD_decompress(out.data(), out.size(), in.data(), in.size());
      if (ZSTD_isError(r)) fail(std::string("zstd chunk is corrupt or truncated (zstd: ") + ZSTD_getErrorName(r) + ")");
      if (r != out.size()) fail("zstd chunk decompresses to " + size_text(r) + ", expected " + size_text(out.size()));
      return;
    }
    case Compressor::Id::Blosc: {
      // Validate the header against the buffer first: c-blosc trusts it otherwise.
      std::size_t nbytes = 0;
      if (in.size() < BLOSC_MIN_HEADER_LENGTH || blosc_cbuffer_validate(in.data(), in.size(), &nbytes) != 0) {
        fail("blosc chunk is corrupt or truncated (" + size_text(in.size()) + ", invalid header)");
      }
      if (nbytes != out.size()) {
        fail("blosc chunk decompresses to " + size_text(nbytes) + ", expected " + size_text(out.size()));
      }
      const int r = blosc_decompress_ctx(in.data(), out.data(), out.size(), 1);
      if (r < 0 || std::size_t(r) != out.size()) fail("blosc chunk is corrupt (decompression failed)");
      return;
    }
  }
}

std::vector<std::byte> encode(const Compressor& c, std::span<const std::byte> in, int typesize) {
  switch (c.id) {
    case Compressor::Id::None: return std::vector<std::byte>(in.begin(), in.end());
    case Compressor::Id::Zlib: return deflate_chunk(in, c.level, false);
    case Compressor::Id::Gzip: return deflate_chunk(in, c.level, true);
    case Compressor::Id::Zstd: {
      std::vector<std::byte> out(ZSTD_compressBound(in.size()));
      const std::size_t r = ZSTD_compress(out.data(), out.size(), in.data(), in.size(), c.level);
      if (ZSTD_isError(r)) throw std::runtime_error(std::string("zstd: ") + ZSTD_getErrorName(r));
      out.resize(r);
      return out;
    }
    case Compressor::Id::Blosc: {
      std::vector<std::byte> out(in.size() + BLOSC_MAX_OVERHEAD);
      const int r = blosc_compress_ctx(c.level, c.shuffle, std::size_t(typesize), in.size(), in.data(), out.data(),
                                       out.size(), c.cname.c_str(), std::size_t(c.blocksize), 1);
      if (r <= 0) throw std::runtime_error("blosc compression failed (" + c.cname + ")");
      out.resize(std::size_t(r));
      return out;
    }
  }
  return {};
}

}  // namespace sl::zarr
