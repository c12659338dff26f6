// Neuroglancer precomputed volumes: the `info` file (neuroglancer's precomputed/volume.md). One JSON
// object: "type" (image or segmentation), "data_type", "num_channels" (must be 1 here) and "scales", the
// finest first, each with "key" (its directory), "size", "resolution" (nm per voxel), "voxel_offset",
// "chunk_sizes" (the first is read), "encoding" (raw or compressed_segmentation, the latter with
// "compressed_segmentation_block_size") and optional "sharding" (neuroglancer_uint64_sharded_v1,
// shard.h).
//
// Mapping to sparseleap's volume (DESIGN.md "Data model"): x, y, z as stored (precomputed chunks are x
// fastest, as Volume is); scale i is level i, so each scale must halve the one before it in x, y and z
// (ceil or floor of an odd size), the rule OME-Zarr levels follow (zarr/meta.h); level 0's resolution is
// the spacing.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/scene/volume.h"
#include "core/util/math.h"

namespace sl::precomputed {

enum class DataType { U8, U16, U32, U64, F32 };
const char* to_string(DataType t);
int data_type_size(DataType t);

enum class Encoding { Raw, CompressedSegmentation };
const char* to_string(Encoding e);

// neuroglancer_uint64_sharded_v1 parameters.
struct Sharding {
  int preshift_bits = 0, minishard_bits = 0, shard_bits = 0;
  bool murmur_hash = false;           // "murmurhash3_x86_128"; otherwise "identity"
  bool gzip_minishard_index = false;  // minishard_index_encoding
  bool gzip_data = false;             // data_encoding
  std::string describe() const;       // for `info`
};

struct Scale {
  std::string key;
  ivec3 size{0}, voxel_offset{0}, chunk{0};
  vec3 resolution{1.0f};
  Encoding encoding = Encoding::Raw;
  ivec3 cseg_block{8};  // compressed_segmentation_block_size
  std::optional<Sharding> sharding;

  ivec3 grid() const { return (size + chunk - 1) / chunk; }  // chunks per axis
  // "scale '8_8_8' (level 0)" for messages.
  std::string name(int level) const;
};

struct Info {
  bool segmentation = false;
  DataType data_type = DataType::U8;
  std::vector<Scale> scales;
  // The voxel type a level decodes to: uint64 narrows to u32 (ids past 2^32 - 1 are an error).
  VoxelType voxel_type() const;
  VolumeDesc desc() const;  // level 0
};

// Parses and checks an `info` file's text. Throws InputError(store, reason) naming the scale at fault.
Info parse_info(const std::string& text, const std::string& store);

}  // namespace sl::precomputed
