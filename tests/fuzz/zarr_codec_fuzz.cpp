// Zarr chunk codecs in memory (cache/formats/zarr/compressor.cpp): byte 0 picks the codec (none, zlib,
// gzip, zstd, blosc), bytes 1-2 the decoded size (little-endian, + 1), the rest is the chunk. Every
// input is also encoded and decoded again, which must give it back (what the writer stores, the
// reader reads).
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <vector>

#include "cache/formats/zarr/compressor.h"
#include "tests/fuzz/fuzz_util.h"

namespace {

sl::zarr::Compressor pick(std::uint8_t b) {
  sl::zarr::Compressor c;
  static const char* const kBlosc[] = {"lz4", "lz4hc", "zstd", "zlib", "blosclz"};
  switch (b % 5) {
    case 0: break;
    case 1: c.id = sl::zarr::Compressor::Id::Zlib; break;
    case 2: c.id = sl::zarr::Compressor::Id::Gzip; break;
    case 3: c.id = sl::zarr::Compressor::Id::Zstd; c.level = 1; break;
    case 4:
      c.id = sl::zarr::Compressor::Id::Blosc;
      c.cname = kBlosc[(b / 5) % 5];
      c.shuffle = (b / 25) % 3;
      break;
  }
  return c;
}

}  // namespace

SL_FUZZ_TARGET(input) {
  const auto* data = reinterpret_cast<const std::uint8_t*>(input.data());
  const std::size_t size = input.size();
  if (size < 3) return;
  const sl::zarr::Compressor c = pick(data[0]);
  const std::size_t out_size = std::size_t(data[1] | (data[2] << 8)) + 1;
  const std::span<const std::byte> in(reinterpret_cast<const std::byte*>(data + 3), size - 3);
  std::vector<std::byte> out(out_size);
  try {
    sl::zarr::decode(c, in, out);
  } catch (const std::runtime_error&) {
  }
  if (!in.empty()) {
    const int typesize = 1 << ((data[0] / 75) % 3);  // 1, 2 or 4 bytes per item (blosc's shuffle)
    const std::vector<std::byte> enc = sl::zarr::encode(c, in, typesize);
    std::vector<std::byte> back(in.size());
    sl::zarr::decode(c, enc, back);  // throws (and so fails) if our own chunk does not read back
    if (std::memcmp(back.data(), in.data(), in.size()) != 0) std::abort();
  }
}
