// The `bytes` codec (array->bytes): elements back to back in C order, little- or big-endian. The
// decoder swaps them to native order (v3_chunk.cpp).
#include <nlohmann/json.hpp>

#include "cache/formats/zarr/codecs/codec.h"

namespace sl::zarr::v3::codecs {

std::string parse_bytes(const nlohmann::json& config, const ChainShape& shape, Chain& chain) {
  const std::string endian =
      config.contains("endian") && config["endian"].is_string() ? config["endian"].get<std::string>() : "";
  if (endian.empty() && shape.elem > 1) fail("bytes codec needs an \"endian\" for multi-byte data");
  if (!endian.empty() && endian != "little" && endian != "big") fail("bytes endian '" + endian + "' is not little or big");
  chain.big_endian = endian == "big";
  return shape.elem > 1 ? "bytes (" + endian + ")" : "bytes";
}

}  // namespace sl::zarr::v3::codecs
