// The `blosc` codec (bytes->bytes), decoded by the v2 compressor (compressor.h). `typesize` is not read:
// a blosc frame records the type size it was shuffled with.
#include <limits>
#include <nlohmann/json.hpp>

#include "cache/formats/zarr/codecs/codec.h"

namespace sl::zarr::v3::codecs {

std::string parse_blosc(const nlohmann::json& config, const ChainShape&, Chain& chain) {
  Compressor c;
  c.id = Compressor::Id::Blosc;
  c.cname = config.value("cname", std::string("zstd"));
  if (c.cname != "lz4" && c.cname != "lz4hc" && c.cname != "zstd" && c.cname != "zlib" && c.cname != "blosclz") {
    fail("blosc cname '" + c.cname + "' is not supported (lz4, lz4hc, zstd, zlib, blosclz)");
  }
  c.level = int_config(config, "clevel", 5, 0, 9, "blosc");
  const std::string sh =
      config.contains("shuffle") && config["shuffle"].is_string() ? config["shuffle"].get<std::string>() : "noshuffle";
  if (sh == "noshuffle") c.shuffle = 0;
  else if (sh == "shuffle") c.shuffle = 1;
  else if (sh == "bitshuffle") c.shuffle = 2;
  else fail("blosc shuffle '" + sh + "' is not one of noshuffle, shuffle, bitshuffle");
  c.blocksize = int_config(config, "blocksize", 0, 0, std::numeric_limits<int>::max(), "blosc");
  chain.steps.push_back({false, c});
  return zarr::describe(c);
}

}  // namespace sl::zarr::v3::codecs
