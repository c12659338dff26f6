// The `gzip` codec (bytes->bytes), decoded by the v2 compressor (compressor.h).
#include <nlohmann/json.hpp>

#include "cache/formats/zarr/codecs/codec.h"

namespace sl::zarr::v3::codecs {

std::string parse_gzip(const nlohmann::json& config, const ChainShape&, Chain& chain) {
  Compressor k;
  k.id = Compressor::Id::Gzip;
  k.level = int_config(config, "level", 5, 0, 9, "gzip");
  chain.steps.push_back({false, k});
  return zarr::describe(k);
}

}  // namespace sl::zarr::v3::codecs
