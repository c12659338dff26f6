// The `crc32c` codec (bytes->bytes): a Castagnoli CRC-32 (RFC 3720) of the encoded bytes appended
// little-endian; verified on decoding.
#include <array>

#include "cache/formats/zarr/codecs/codec.h"

namespace sl::zarr::v3 {

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

namespace codecs {

std::string parse_crc32c(const nlohmann::json&, const ChainShape&, Chain& chain) {
  chain.steps.push_back({true, {}});
  return "crc32c";
}

void strip_crc32c(std::vector<std::byte>& in) {
  if (in.size() < 4) fail("too short (" + std::to_string(in.size()) + " bytes) for its crc32c checksum");
  std::uint32_t stored = 0;
  for (int b = 3; b >= 0; --b) stored = (stored << 8) | std::uint32_t(in[in.size() - 4 + std::size_t(b)]);
  const std::uint32_t got = crc32c(in.data(), in.size() - 4);
  if (got != stored) {
    fail("crc32c checksum mismatch (stored " + std::to_string(stored) + ", computed " + std::to_string(got) +
         "): the chunk is corrupt");
  }
  in.resize(in.size() - 4);
}

}  // namespace codecs
}  // namespace sl::zarr::v3
