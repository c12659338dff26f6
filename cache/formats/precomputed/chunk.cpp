#include "cache/formats/precomputed/chunk.h"

#include <zlib.h>

#include <bit>
#include <cstdint>
#include <cstring>
#include <limits>
#include <stdexcept>

namespace sl::precomputed {
namespace {

static_assert(std::endian::native == std::endian::little, "precomputed data are little-endian; add a swap for this host");

[[noreturn]] void fail(const std::string& why) { throw std::runtime_error(why); }

std::uint32_t narrow_id(std::uint64_t v) {
  if (v > std::numeric_limits<std::uint32_t>::max()) {
    fail("label id " + std::to_string(v) + " does not fit in 32 bits (sparseleap labels are u32)");
  }
  return std::uint32_t(v);
}

// Raw voxels: as stored, uint64 narrowed.
std::vector<std::byte> decode_raw(const Info& info, std::span<const std::byte> in, std::size_t n) {
  const std::size_t elem = std::size_t(data_type_size(info.data_type));
  if (in.size() != n * elem) {
    fail("raw chunk holds " + std::to_string(in.size()) + " bytes, expected " + std::to_string(n * elem));
  }
  if (info.data_type != DataType::U64) return {in.begin(), in.end()};
  std::vector<std::byte> out(n * 4);
  for (std::size_t i = 0; i < n; ++i) {
    std::uint64_t v;
    std::memcpy(&v, in.data() + i * 8, 8);
    const std::uint32_t w = narrow_id(v);
    std::memcpy(out.data() + i * 4, &w, 4);
  }
  return out;
}

// compressed_segmentation, one channel: word 0 is the channel's offset; the channel holds one 2-word
// header per block (x fastest): lookup-table offset (24 bits) | encoded bits (8 bits), then the offset
// of the block's packed indices; offsets are in 32-bit words from the channel's start. Indices are
// packed LSB first over the whole block (its full size, also where the chunk is clipped).
std::vector<std::byte> decode_cseg(const Info& info, const Scale& s, std::span<const std::byte> in, ivec3 shape) {
  if (in.size() % 4 != 0 || in.size() < 4) fail("compressed_segmentation data of " + std::to_string(in.size()) + " bytes is not a whole number of 32-bit words");
  const std::size_t nw = in.size() / 4;
  const auto word = [&](std::uint64_t i) {
    std::uint32_t w;
    std::memcpy(&w, in.data() + i * 4, 4);
    return w;
  };
  const bool wide = info.data_type == DataType::U64;
  const std::uint64_t base = word(0);
  const ivec3 bs = s.cseg_block;
  const ivec3 gb = (shape + bs - 1) / bs;
  const std::uint64_t blocks = std::uint64_t(gb.x) * std::uint64_t(gb.y) * std::uint64_t(gb.z);
  if (base < 1 || base + 2 * blocks > nw) {
    fail("compressed_segmentation channel offset " + std::to_string(base) + " leaves no room for the " +
         std::to_string(blocks) + " block headers in " + std::to_string(nw) + " words");
  }
  std::vector<std::byte> out(std::size_t(shape.x) * std::size_t(shape.y) * std::size_t(shape.z) * 4);
  auto* dst = reinterpret_cast<std::uint32_t*>(out.data());
  for (int bz = 0; bz < gb.z; ++bz)
    for (int by = 0; by < gb.y; ++by)
      for (int bx = 0; bx < gb.x; ++bx) {
        const std::uint64_t b = (std::uint64_t(bz) * std::uint64_t(gb.y) + std::uint64_t(by)) * std::uint64_t(gb.x) + std::uint64_t(bx);
        const std::uint32_t h0 = word(base + 2 * b), h1 = word(base + 2 * b + 1);
        const std::uint64_t table = base + (h0 & 0xffffffu), values = base + h1;
        const int bits = int(h0 >> 24);
        const std::string where = "compressed_segmentation block " + std::to_string(b);
        if (bits != 0 && bits != 1 && bits != 2 && bits != 4 && bits != 8 && bits != 16 && bits != 32) {
          fail(where + ": " + std::to_string(bits) + " encoded bits (0, 1, 2, 4, 8, 16 or 32)");
        }
        const std::uint64_t voxels = std::uint64_t(bs.x) * std::uint64_t(bs.y) * std::uint64_t(bs.z);
        if (bits > 0 && values + (voxels * std::uint64_t(bits) + 31) / 32 > nw) {
          fail(where + ": packed indices at word " + std::to_string(values) + " run past the end (" + std::to_string(nw) + " words)");
        }
        const std::uint32_t mask = bits == 32 ? 0xffffffffu : (1u << bits) - 1u;
        const ivec3 o = ivec3(bx, by, bz) * bs;
        const ivec3 e = glm::min(shape - o, bs);
        for (int z = 0; z < e.z; ++z)
          for (int y = 0; y < e.y; ++y)
            for (int x = 0; x < e.x; ++x) {
              std::uint64_t idx = 0;
              if (bits > 0) {
                const std::uint64_t bit = ((std::uint64_t(z) * std::uint64_t(bs.y) + std::uint64_t(y)) * std::uint64_t(bs.x) + std::uint64_t(x)) * std::uint64_t(bits);
                idx = (word(values + bit / 32) >> (bit % 32)) & mask;
              }
              const std::uint64_t t = table + idx * (wide ? 2 : 1);
              if (t + (wide ? 2 : 1) > nw) {
                fail(where + ": lookup-table entry " + std::to_string(idx) + " at word " + std::to_string(t) + " lies past the end (" + std::to_string(nw) + " words)");
              }
              const std::uint64_t id = wide ? (std::uint64_t(word(t)) | (std::uint64_t(word(t + 1)) << 32)) : word(t);
              dst[(std::size_t(o.z + z) * std::size_t(shape.y) + std::size_t(o.y + y)) * std::size_t(shape.x) + std::size_t(o.x + x)] = narrow_id(id);
            }
      }
  return out;
}

}  // namespace

bool is_gzip(std::span<const std::byte> b) {
  return b.size() >= 2 && b[0] == std::byte{0x1f} && b[1] == std::byte{0x8b};
}

std::vector<std::byte> gunzip(std::span<const std::byte> in, std::size_t max_out) {
  z_stream zs{};
  if (inflateInit2(&zs, 15 + 16) != Z_OK) throw std::bad_alloc();
  std::vector<std::byte> out;
  zs.next_in = reinterpret_cast<Bytef*>(const_cast<std::byte*>(in.data()));
  zs.avail_in = uInt(in.size());
  int ret = Z_OK;
  while (ret != Z_STREAM_END) {
    if (out.size() >= max_out + 1) {
      inflateEnd(&zs);
      fail("gzip data decode to more than the " + std::to_string(max_out) + " bytes expected");
    }
    const std::size_t done = out.size();
    out.resize(std::min(max_out + 1, std::max<std::size_t>(done * 2, 4096)));
    zs.next_out = reinterpret_cast<Bytef*>(out.data() + done);
    zs.avail_out = uInt(out.size() - done);
    ret = inflate(&zs, Z_NO_FLUSH);
    out.resize(out.size() - zs.avail_out);
    if (ret == Z_STREAM_END) break;
    if (ret != Z_OK && ret != Z_BUF_ERROR) {
      inflateEnd(&zs);
      fail(std::string("corrupt gzip data (") + (zs.msg ? zs.msg : "zlib error") + ")");
    }
    if (ret == Z_BUF_ERROR && zs.avail_in == 0) {
      inflateEnd(&zs);
      fail("gzip data end early");
    }
  }
  inflateEnd(&zs);
  if (out.size() > max_out) fail("gzip data decode to more than the " + std::to_string(max_out) + " bytes expected");
  return out;
}

std::vector<std::byte> decode_chunk(const Info& info, const Scale& s, std::span<const std::byte> data, ivec3 shape) {
  const std::size_t n = std::size_t(shape.x) * std::size_t(shape.y) * std::size_t(shape.z);
  const std::size_t raw_bytes = n * std::size_t(data_type_size(info.data_type));
  std::vector<std::byte> inflated;
  // A raw chunk has exactly its size; one of another size that starts as gzip is gzip-wrapped. A
  // compressed_segmentation chunk starts with the channel offset 1 (01 00 00 00), never with 1f 8b.
  if (is_gzip(data) && (s.encoding != Encoding::Raw || data.size() != raw_bytes)) {
    // Bound for compressed_segmentation: every block at 32 bits plus a table entry per voxel.
    inflated = gunzip(data, s.encoding == Encoding::Raw ? raw_bytes : 16 * n + (std::size_t(1) << 20));
    data = inflated;
  }
  if (s.encoding == Encoding::Raw) return decode_raw(info, data, n);
  return decode_cseg(info, s, data, shape);
}

}  // namespace sl::precomputed
