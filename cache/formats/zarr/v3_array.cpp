#include "cache/formats/zarr/v3_array.h"

#include <cmath>
#include <cstring>
#include <limits>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "cache/formats/zarr/v3_codec.h"
#include "core/util/checked.h"
#include "core/util/json_util.h"

namespace sl::zarr::v3 {
namespace {

using json = nlohmann::json;

[[noreturn]] void fail(const std::string& why) { throw std::runtime_error(why); }

// Most inner chunks in one shard: its index (16 bytes each) is read whole and stays within
// byte_store.h's kMaxIndexBytes (the largest chunk is meta.h's kMaxChunkBytes).
constexpr std::uint64_t kMaxInnerChunksPerShard = std::uint64_t(1) << 22;

std::vector<std::int64_t> positive_list(const json& j, const std::string& what, std::size_t n) {
  if (!j.is_array() || (n && j.size() != n) || j.empty()) {
    fail(what + " must be a list of " + (n ? std::to_string(n) + " " : std::string()) + "positive integers");
  }
  std::vector<std::int64_t> v;
  for (const json& e : j) {
    if (!e.is_number_integer() || e.get<long long>() < 1 || e.get<long long>() > std::numeric_limits<std::int32_t>::max()) {
      fail(what + " entry " + e.dump() + " is out of range");
    }
    v.push_back(e.get<std::int64_t>());
  }
  return v;
}

Stored parse_data_type(const json& j, VoxelType& t) {
  if (!j.is_string()) fail("data_type must be a string (extension data types are not supported)");
  const std::string s = j.get<std::string>();
  if (s == "uint8") return t = VoxelType::U8, Stored::U8;
  if (s == "uint16") return t = VoxelType::U16, Stored::U16;
  if (s == "uint32") return t = VoxelType::U32, Stored::U32;
  if (s == "float32") return t = VoxelType::F32, Stored::F32;
  if (s == "int16") return t = VoxelType::F32, Stored::I16;
  fail("data_type '" + s + "' is not supported (uint8, uint16, uint32, float32, int16)");
}

double parse_fill(const json& fv, Stored s) {
  if (fv.is_number()) return fv.get<double>();
  if (fv.is_string() && s == Stored::F32) {
    const std::string v = fv.get<std::string>();
    if (v == "NaN") return std::numeric_limits<double>::quiet_NaN();
    if (v == "Infinity") return std::numeric_limits<double>::infinity();
    if (v == "-Infinity") return -std::numeric_limits<double>::infinity();
    // The spec's raw form: the float's bits in hex.
    if (v.size() == 10 && v.compare(0, 2, "0x") == 0 && v.find_first_not_of("0123456789abcdefABCDEF", 2) == std::string::npos) {
      const std::uint32_t bits = std::uint32_t(std::stoul(v.substr(2), nullptr, 16));
      float f;
      std::memcpy(&f, &bits, 4);
      return double(f);
    }
  }
  fail("fill_value " + fv.dump() + " is not a number of the data type");
}

}  // namespace

namespace {

ArrayMeta parse_array_checked(const json& j) {
  if (!j.is_object()) fail("zarr.json is not a JSON object");
  if (!j.contains("zarr_format") || j["zarr_format"] != 3) fail("zarr_format must be 3");
  if (j.value("node_type", std::string()) != "array") fail("node_type must be \"array\"");
  auto a = std::make_shared<ArrayCodecs>();
  ArrayMeta m;
  m.shape = positive_list(j.contains("shape") ? j["shape"] : json(), "shape", 0);
  const std::size_t nd = m.shape.size();
  if (nd < 3 || nd > 5) {
    fail("array has " + std::to_string(nd) + " dimensions; expected 3 (z, y, x) or 4-5 with singleton leading axes");
  }
  for (std::size_t i = 0; i + 3 < nd; ++i) {
    if (m.shape[i] != 1) {
      fail("leading (t/c) axis " + std::to_string(i) + " has size " + std::to_string(m.shape[i]) +
           "; only size 1 is supported");
    }
  }
  a->stored = parse_data_type(j.contains("data_type") ? j["data_type"] : json(), m.type);
  const json grid = j.value("chunk_grid", json());
  if (!grid.is_object() || grid.value("name", std::string()) != "regular" || !grid.contains("configuration")) {
    fail("chunk_grid must be {\"name\": \"regular\", \"configuration\": {\"chunk_shape\": [...]}}");
  }
  a->grid = positive_list(grid["configuration"].value("chunk_shape", json()), "chunk_grid chunk_shape", nd);
  const json keys = j.value("chunk_key_encoding", json());
  const std::string kname = keys.is_object() ? keys.value("name", std::string()) : "";
  if (kname != "default" && kname != "v2") fail("chunk_key_encoding must be named \"default\" or \"v2\"");
  a->default_keys = kname == "default";
  a->separator = a->default_keys ? '/' : '.';
  if (keys.contains("configuration") && keys["configuration"].contains("separator")) {
    const json& sep = keys["configuration"]["separator"];
    if (!sep.is_string() || (sep != "/" && sep != ".")) fail("chunk_key_encoding separator must be \"/\" or \".\"");
    a->separator = sep.get<std::string>()[0];
  }
  if (j.contains("storage_transformers") && !(j["storage_transformers"].is_array() && j["storage_transformers"].empty())) {
    fail("storage_transformers are not supported");
  }
  m.fill = parse_fill(j.value("fill_value", json()), a->stored);
  a->chain = parse_chain(j.value("codecs", json()), a->grid, stored_size(a->stored), &a->shard);
  m.chunks = a->shard ? a->shard->inner : a->grid;
  // Sizes from the metadata, checked before anything is sized from them (core/util/checked.h): the
  // grid of chunks (of shards, when sharded) is ceil(shape / chunk) per axis, and its product.
  std::vector<std::int64_t> chunk_grid(nd);
  for (std::size_t i = 0; i < nd; ++i) {
    chunk_grid[i] = std::int64_t(checked_ceil_div(std::uint64_t(m.shape[i]), std::uint64_t(a->grid[i]),
                                                  a->shard ? "shard grid" : "chunk grid"));
  }
  checked_product(std::span<const std::int64_t>(chunk_grid), a->shard ? "shard grid" : "chunk grid");
  if (a->shard) {
    std::vector<std::int64_t> per_shard(nd);
    for (std::size_t i = 0; i < nd; ++i) per_shard[i] = a->grid[i] / a->shard->inner[i];
    const std::uint64_t n = checked_product(std::span<const std::int64_t>(per_shard), "inner chunks per shard");
    if (n > kMaxInnerChunksPerShard) {
      fail("shards of " + std::to_string(n) + " inner chunks exceed the 2^22 limit (a 64 MiB shard index)");
    }
  }
  const std::uint64_t bytes =
      checked_product(std::span<const std::int64_t>(m.chunks), "decoded chunk bytes", std::uint64_t(voxel_size(m.type)));
  if (bytes > kMaxChunkBytes) fail("chunks of " + std::to_string(bytes) + " decoded bytes exceed the 1 GiB limit");
  if (j.contains("dimension_names") && !j["dimension_names"].is_null()) {
    const json& dn = j["dimension_names"];
    if (!dn.is_array() || dn.size() != nd) fail("dimension_names must list one name (or null) per axis");
    for (const json& n : dn) {
      if (!n.is_string() && !n.is_null()) fail("dimension_names must be strings or null");
      m.dimension_names.push_back(n.is_string() ? n.get<std::string>() : "");
    }
  }
  m.v3 = std::move(a);
  return m;
}

}  // namespace

// The checks above read values of a type they test first, but a member of an unexpected type (a
// number where a name belongs) can still reach one of nlohmann's typed reads: json_typed makes it the
// metadata's fault like every other refusal here.
ArrayMeta parse_array(const json& j) { return json_typed([&] { return parse_array_checked(j); }); }

}  // namespace sl::zarr::v3
