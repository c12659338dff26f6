#include "cache/formats/precomputed/info.h"

#include <bit>
#include <cmath>
#include <nlohmann/json.hpp>

#include "cache/stores/store_key.h"
#include "core/util/checked.h"
#include "core/util/error.h"

namespace sl::precomputed {
namespace {

using json = nlohmann::json;

// Limits that keep one chunk's buffers and every product of sizes far from overflow.
constexpr std::int64_t kMaxSize = std::int64_t(1) << 30;
constexpr std::int64_t kMaxOffset = std::int64_t(1) << 30;
constexpr std::uint64_t kMaxChunkVoxels = std::uint64_t(1) << 24;  // 256³, 64 MiB of u32

std::string vec_text(ivec3 v) { return std::to_string(v.x) + "x" + std::to_string(v.y) + "x" + std::to_string(v.z); }

struct Ctx {
  const std::string& store;
  std::string where;  // "info" or "info: scale 'K' (level L)"
  [[noreturn]] void fail(const std::string& why) const { throw InputError(store, where + ": " + why); }
};

ivec3 int3(const json& o, const char* key, std::int64_t lo, std::int64_t hi, const Ctx& c) {
  if (!o.contains(key)) c.fail(std::string("lacks \"") + key + "\"");
  const json& a = o[key];
  if (!a.is_array() || a.size() != 3) c.fail(std::string("\"") + key + "\" must be an array of 3 integers");
  ivec3 v;
  for (int i = 0; i < 3; ++i) {
    if (!a[std::size_t(i)].is_number_integer() || a[std::size_t(i)].get<std::int64_t>() < lo ||
        a[std::size_t(i)].get<std::int64_t>() > hi) {
      c.fail(std::string("\"") + key + "\" must hold integers in " + std::to_string(lo) + ".." + std::to_string(hi));
    }
    v[i] = int(a[std::size_t(i)].get<std::int64_t>());
  }
  return v;
}

int bits(const json& o, const char* key, const Ctx& c) {
  if (!o.contains(key) || !o[key].is_number_integer() || o[key].get<std::int64_t>() < 0 || o[key].get<std::int64_t>() > 64) {
    c.fail(std::string("sharding \"") + key + "\" must be an integer in 0..64");
  }
  return o[key].get<int>();
}

bool gzip_encoding(const json& o, const char* key, const Ctx& c) {
  if (!o.contains(key)) return false;
  if (o[key] == "raw") return false;
  if (o[key] == "gzip") return true;
  c.fail(std::string("sharding \"") + key + "\" must be \"raw\" or \"gzip\"");
}

Sharding parse_sharding(const json& s, const Ctx& c) {
  if (!s.is_object()) c.fail("\"sharding\" must be an object");
  if (!s.contains("@type") || s["@type"] != "neuroglancer_uint64_sharded_v1") {
    c.fail("sharding \"@type\" must be \"neuroglancer_uint64_sharded_v1\"");
  }
  Sharding r;
  r.preshift_bits = bits(s, "preshift_bits", c);
  r.minishard_bits = bits(s, "minishard_bits", c);
  r.shard_bits = bits(s, "shard_bits", c);
  // The shard index has 2^minishard_bits entries; 32 bits is already a 64 GiB index.
  if (r.minishard_bits > 32) c.fail("sharding \"minishard_bits\" " + std::to_string(r.minishard_bits) + " exceeds 32");
  if (r.minishard_bits + r.shard_bits > 64) c.fail("sharding minishard_bits + shard_bits exceed 64");
  if (!s.contains("hash") || !s["hash"].is_string()) c.fail("sharding lacks \"hash\"");
  const std::string h = s["hash"].get<std::string>();
  if (h == "murmurhash3_x86_128") r.murmur_hash = true;
  else if (h != "identity") c.fail("sharding hash '" + h + "' is not identity or murmurhash3_x86_128");
  r.gzip_minishard_index = gzip_encoding(s, "minishard_index_encoding", c);
  r.gzip_data = gzip_encoding(s, "data_encoding", c);
  return r;
}

DataType parse_data_type(const json& j, const Ctx& c) {
  if (!j.is_string()) c.fail("\"data_type\" must be a string");
  const std::string t = j.get<std::string>();
  if (t == "uint8") return DataType::U8;
  if (t == "uint16") return DataType::U16;
  if (t == "uint32") return DataType::U32;
  if (t == "uint64") return DataType::U64;
  if (t == "float32") return DataType::F32;
  c.fail("data_type '" + t + "' is not supported (uint8, uint16, uint32, uint64, float32)");
}

}  // namespace

const char* to_string(DataType t) {
  switch (t) {
    case DataType::U8: return "uint8";
    case DataType::U16: return "uint16";
    case DataType::U32: return "uint32";
    case DataType::U64: return "uint64";
    case DataType::F32: return "float32";
  }
  return "?";
}

int data_type_size(DataType t) { return t == DataType::U8 ? 1 : t == DataType::U16 ? 2 : t == DataType::U64 ? 8 : 4; }

const char* to_string(Encoding e) { return e == Encoding::Raw ? "raw" : "compressed_segmentation"; }

std::string Sharding::describe() const {
  return "neuroglancer_uint64_sharded_v1 (preshift " + std::to_string(preshift_bits) + ", minishard " +
         std::to_string(minishard_bits) + ", shard " + std::to_string(shard_bits) + " bits; " +
         (murmur_hash ? "murmurhash3_x86_128" : "identity") + " hash; minishard index " +
         (gzip_minishard_index ? "gzip" : "raw") + ", data " + (gzip_data ? "gzip" : "raw") + ")";
}

std::string Scale::name(int level) const { return "scale '" + key + "' (level " + std::to_string(level) + ")"; }

VoxelType Info::voxel_type() const {
  switch (data_type) {
    case DataType::U8: return VoxelType::U8;
    case DataType::U16: return VoxelType::U16;
    case DataType::U32:
    case DataType::U64: return VoxelType::U32;
    case DataType::F32: return VoxelType::F32;
  }
  return VoxelType::U8;
}

VolumeDesc Info::desc() const { return VolumeDesc{scales[0].size, scales[0].resolution, voxel_type()}; }

Info parse_info(const std::string& text, const std::string& store) {
  Ctx c{store, "info"};
  json j;
  try {
    j = json::parse(text);
  } catch (const json::exception& e) {
    c.fail(std::string("malformed JSON (") + e.what() + ")");
  }
  if (!j.is_object()) c.fail("must be a JSON object");
  if (j.contains("@type") && j["@type"] != "neuroglancer_multiscale_volume") {
    c.fail("\"@type\" must be \"neuroglancer_multiscale_volume\"");
  }
  Info info;
  if (!j.contains("type") || (j["type"] != "image" && j["type"] != "segmentation")) {
    c.fail("\"type\" must be \"image\" or \"segmentation\"");
  }
  info.segmentation = j["type"] == "segmentation";
  if (!j.contains("data_type")) c.fail("lacks \"data_type\"");
  info.data_type = parse_data_type(j["data_type"], c);
  if (!j.contains("num_channels") || !j["num_channels"].is_number_integer()) c.fail("lacks an integer \"num_channels\"");
  if (j["num_channels"].get<std::int64_t>() != 1) {
    c.fail("num_channels " + j["num_channels"].dump() + " is not supported (volumes have one channel)");
  }
  if (!j.contains("scales") || !j["scales"].is_array() || j["scales"].empty()) c.fail("\"scales\" must be a non-empty array");
  for (std::size_t l = 0; l < j["scales"].size(); ++l) {
    const json& s = j["scales"][l];
    if (!s.is_object()) c.fail("scale " + std::to_string(l) + " is not an object");
    Scale sc;
    if (!s.contains("key") || !s["key"].is_string() || s["key"].get<std::string>().empty()) {
      c.fail("scale " + std::to_string(l) + " lacks a string \"key\"");
    }
    sc.key = s["key"].get<std::string>();
    Ctx sctx{store, "info: " + sc.name(int(l))};
    // A key names a directory below the volume's own, never a way out of it: checked as every store
    // checks the keys it reads (store_key.h), after every percent-decoding a server would apply.
    try {
      if (store_key(sc.key).empty()) sctx.fail("key must name a directory inside the volume");
    } catch (const InputError&) {
      throw;
    } catch (const std::runtime_error& e) {
      sctx.fail(e.what());
    }
    sc.size = int3(s, "size", 1, kMaxSize, sctx);
    sc.voxel_offset = int3(s, "voxel_offset", -kMaxOffset, kMaxOffset, sctx);
    if (!s.contains("resolution") || !s["resolution"].is_array() || s["resolution"].size() != 3) {
      sctx.fail("\"resolution\" must be an array of 3 numbers");
    }
    for (int i = 0; i < 3; ++i) {
      const json& r = s["resolution"][std::size_t(i)];
      if (!r.is_number()) sctx.fail("\"resolution\" must hold positive finite numbers");
      if (const std::string why = voxel_size_problem(r.get<double>()); !why.empty()) {
        sctx.fail("\"resolution\" " + r.dump() + " along " + "xyz"[i] + " " + why + " (a voxel size sparseleap can place in world space)");
      }
      sc.resolution[i] = float(r.get<double>());
    }
    if (!s.contains("chunk_sizes") || !s["chunk_sizes"].is_array() || s["chunk_sizes"].empty()) {
      sctx.fail("\"chunk_sizes\" must be a non-empty array of [x, y, z]");
    }
    json first = json::object();
    first["chunk"] = s["chunk_sizes"][0];
    sc.chunk = int3(first, "chunk", 1, kMaxSize, sctx);
    std::uint64_t chunk_voxels = 0;
    try {
      chunk_voxels = checked_product({sc.chunk.x, sc.chunk.y, sc.chunk.z}, "chunk voxels");
    } catch (const SizeOverflow& e) {
      sctx.fail(e.what());
    }
    if (chunk_voxels > kMaxChunkVoxels) {
      sctx.fail("chunk " + vec_text(sc.chunk) + " holds more than 2^24 voxels");
    }
    if (!s.contains("encoding") || !s["encoding"].is_string()) sctx.fail("lacks a string \"encoding\"");
    const std::string enc = s["encoding"].get<std::string>();
    if (enc == "compressed_segmentation") {
      if (info.data_type != DataType::U32 && info.data_type != DataType::U64) {
        sctx.fail("compressed_segmentation needs data_type uint32 or uint64, not " + std::string(to_string(info.data_type)));
      }
      sc.encoding = Encoding::CompressedSegmentation;
      sc.cseg_block = int3(s, "compressed_segmentation_block_size", 1, 1024, sctx);
    } else if (enc != "raw") {
      sctx.fail("encoding '" + enc + "' is not supported (raw, compressed_segmentation)");
    }
    if (s.contains("sharding")) {
      sc.sharding = parse_sharding(s["sharding"], sctx);
      // A chunk's id is the compressed Morton code of its grid position (shard.h): its bits must fit
      // 64, or ids of different chunks would collide.
      int id_bits = 0;
      for (int i = 0; i < 3; ++i) id_bits += int(std::bit_width(std::uint32_t(sc.grid()[i] - 1)));
      if (id_bits > 64) {
        sctx.fail("chunk grid " + vec_text(sc.grid()) + " needs " + std::to_string(id_bits) +
                  " bits of sharded chunk id, more than 64");
      }
    }
    if (l > 0) {
      const ivec3 p = info.scales[l - 1].size;
      for (int i = 0; i < 3; ++i) {
        if (sc.size[i] != p[i] / 2 && sc.size[i] != (p[i] + 1) / 2) {
          sctx.fail("size " + vec_text(sc.size) + " does not halve the previous scale's " + vec_text(p) +
                    " in x, y and z (levels must be 2x reductions)");
        }
      }
    }
    info.scales.push_back(std::move(sc));
  }
  validate_desc(info.desc(), store);
  return info;
}

}  // namespace sl::precomputed
