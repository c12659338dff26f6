#include "cache/formats/zarr/v3_writer.h"

#include <limits>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "cache/formats/zarr/v3_codec.h"

namespace sl::zarr::v3 {
namespace {

using json = nlohmann::json;

json codec_json(const Compressor& c, int elem) {
  switch (c.id) {
    case Compressor::Id::None: return nullptr;
    case Compressor::Id::Zlib: throw std::runtime_error("zlib has no Zarr v3 codec (use gzip)");
    case Compressor::Id::Gzip: return {{"name", "gzip"}, {"configuration", {{"level", c.level}}}};
    case Compressor::Id::Zstd: return {{"name", "zstd"}, {"configuration", {{"level", c.level}, {"checksum", false}}}};
    case Compressor::Id::Blosc:
      return {{"name", "blosc"},
              {"configuration",
               {{"cname", c.cname},
                {"clevel", c.level},
                {"shuffle", c.shuffle == 0 ? "noshuffle" : c.shuffle == 1 ? "shuffle" : "bitshuffle"},
                {"typesize", elem},
                {"blocksize", c.blocksize}}}};
  }
  return nullptr;
}

const char* data_type(VoxelType t) {
  switch (t) {
    case VoxelType::U8: return "uint8";
    case VoxelType::U16: return "uint16";
    case VoxelType::U32: return "uint32";
    case VoxelType::F32: return "float32";
  }
  return "?";
}

void put_u64(std::vector<std::byte>& b, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) b.push_back(std::byte((v >> (8 * i)) & 0xFF));
}

}  // namespace

json array_json(ivec3 dims, int chunk, int shard, VoxelType type, const Compressor& c) {
  const int elem = voxel_size(type);
  json inner = json::array({elem > 1 ? json{{"name", "bytes"}, {"configuration", {{"endian", "little"}}}}
                                     : json{{"name", "bytes"}}});
  const json k = codec_json(c, elem);
  if (!k.is_null()) inner.push_back(k);
  const int grid = shard > 0 ? chunk * shard : chunk;
  json codecs = inner;
  if (shard > 0) {
    codecs = json::array({{{"name", "sharding_indexed"},
                           {"configuration",
                            {{"chunk_shape", {chunk, chunk, chunk}},
                             {"codecs", inner},
                             {"index_codecs", json::array({{{"name", "bytes"}, {"configuration", {{"endian", "little"}}}},
                                                           {{"name", "crc32c"}}})},
                             {"index_location", "end"}}}}});
  }
  return {{"zarr_format", 3},
          {"node_type", "array"},
          {"shape", {dims.z, dims.y, dims.x}},
          {"data_type", data_type(type)},
          {"chunk_grid", {{"name", "regular"}, {"configuration", {{"chunk_shape", {grid, grid, grid}}}}}},
          {"chunk_key_encoding", {{"name", "default"}, {"configuration", {{"separator", "/"}}}}},
          {"fill_value", 0},
          {"codecs", codecs},
          {"dimension_names", {"z", "y", "x"}},
          {"attributes", json::object()},
          {"storage_transformers", json::array()}};
}

std::vector<std::byte> assemble_shard(const std::vector<std::optional<std::vector<std::byte>>>& chunks) {
  std::vector<std::byte> out, index;
  constexpr std::uint64_t kEmpty = std::numeric_limits<std::uint64_t>::max();
  for (const auto& c : chunks) {
    if (!c) {
      put_u64(index, kEmpty);
      put_u64(index, kEmpty);
      continue;
    }
    put_u64(index, out.size());
    put_u64(index, c->size());
    out.insert(out.end(), c->begin(), c->end());
  }
  if (out.empty()) return out;
  const std::uint32_t crc = crc32c(index.data(), index.size());
  for (int i = 0; i < 4; ++i) index.push_back(std::byte((crc >> (8 * i)) & 0xFF));
  out.insert(out.end(), index.begin(), index.end());
  return out;
}

}  // namespace sl::zarr::v3
