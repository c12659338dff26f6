#include "core/util/checked.h"
#include "cache/formats/zarr/codecs/codec.h"

#include <nlohmann/json.hpp>
#include <stdexcept>

namespace sl::zarr::v3::codecs {
namespace {

constexpr Codec kCodecs[] = {
    {"transpose", Role::ArrayToArray, &parse_transpose},
    {"bytes", Role::ArrayToBytes, &parse_bytes},
    {"sharding_indexed", Role::Sharding, &parse_sharding_indexed},
    {"gzip", Role::Compressor, &parse_gzip},
    {"zstd", Role::Compressor, &parse_zstd},
    {"blosc", Role::Compressor, &parse_blosc},
    {"crc32c", Role::Checksum, &parse_crc32c},
};

}  // namespace

std::span<const Codec> all() { return kCodecs; }

const Codec* find(std::string_view name) {
  for (const Codec& c : kCodecs) {
    if (c.name == name) return &c;
  }
  return nullptr;
}

void fail(const std::string& why) { throw std::runtime_error(why); }

int int_config(const nlohmann::json& config, const char* key, int def, int lo, int hi, const std::string& codec) {
  if (!config.contains(key)) return def;
  const nlohmann::json& v = config[key];
  if (!v.is_number_integer() || v.get<long long>() < lo || v.get<long long>() > hi) {
    fail(codec + " configuration '" + key + "' must be an integer in " + std::to_string(lo) + ".." + std::to_string(hi));
  }
  return v.get<int>();
}

std::string shape_text(const std::vector<std::int64_t>& shape) {
  std::string t;
  for (std::size_t i = 0; i < shape.size(); ++i) {
    if (i) t += 'x';
    t += std::to_string(shape[i]);
  }
  return t;
}

std::size_t element_count(const std::vector<std::int64_t>& shape) {
  return std::size_t(checked_product(std::span<const std::int64_t>(shape), "elements of shape " + shape_text(shape)));
}

}  // namespace sl::zarr::v3::codecs
