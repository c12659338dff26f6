// OME-Zarr (NGFF 0.4) on Zarr v2 and (NGFF 0.5) on Zarr v3: the metadata of a store. A store is a directory; its root group's
// .zattrs "multiscales" names one array per level (datasets[].path) with per-level scale transforms,
// and an optional "labels" group holds label images with their own multiscales (NGFF's image-label).
// A bare Zarr v2 array (a directory with .zarray) is read as a one-level store. Zarr v3 (zarr.json,
// zarr3_meta.h) has the same layout with "multiscales" and "labels" under the group's attributes.ome.
//
// Mapping to sparseleap's volume (DESIGN.md §3): the last three array axes are z, y, x; zarr's C
// order makes x fastest, exactly as Volume stores it. Leading axes (t, c) must have size 1. Each level
// must halve the previous one in x, y and z (ceil or floor of an odd size); other pyramids are refused
// with a clear message rather than resampled.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "cache/formats/zarr_codec.h"
#include "core/math.h"
#include "core/volume.h"

namespace sl::zarr {

namespace v3 {
struct ArrayCodecs;
}

// One .zarray, or one v3 array's zarr.json.
struct ArrayMeta {
  std::vector<std::int64_t> shape, chunks;  // zarr order (slowest first)
  VoxelType type = VoxelType::U8;
  bool big_endian = false;
  double fill = 0.0;         // null fill_value reads as 0
  char separator = '.';      // dimension_separator: '.' or '/'
  Compressor compressor;
  // Zarr v3 only: codecs, chunk keys and shards (zarr3_codec.h); `chunks` is then the read grid (the
  // inner chunks of a sharded array) and decoded chunks are already in native order.
  std::shared_ptr<const v3::ArrayCodecs> v3;
  std::vector<std::string> dimension_names;  // v3 only, "" for a null name

  int ndim() const { return int(shape.size()); }
  ivec3 dims() const;        // x, y, z of the last three axes
  ivec3 chunk_dims() const;
  std::size_t chunk_bytes() const;  // decoded bytes of one (full-size) chunk
  // Relative path of chunk (cx, cy, cz) within the array directory, with 0 for leading axes.
  std::string chunk_key(ivec3 c) const;
};

// The compressor (v2) or codec chain (v3), for `info`.
std::string describe(const ArrayMeta& m);

// The dtype string for a type, little-endian ("|u1", "<u2", "<u4", "<f4").
std::string dtype_string(VoxelType t);
nlohmann::json to_json(const ArrayMeta& m);

struct Level {
  std::string path;  // relative to the multiscale group
  ArrayMeta meta;
  ivec3 dims{0};
  vec3 scale{1.0f};  // voxel size (x, y, z) from coordinateTransformations; 1 when absent
};

struct Multiscale {
  std::filesystem::path dir;  // the group holding the level arrays
  std::string what;           // "" for the image, "labels/NAME" for a label image (for messages)
  std::vector<Level> levels;
  VolumeDesc desc;            // level 0: dims, spacing (level-0 scale), type
};

struct StoreInfo {
  std::string path;                     // as the user gave it (errors name it)
  Multiscale image;
  std::optional<Multiscale> labels;     // the first entry of labels/.zattrs "labels", if any
  std::vector<std::string> label_names; // every entry
};

// Reads and checks all metadata of the store at `path` (no chunk data). Every problem throws
// InputError(path, reason) naming the level and array at fault.
StoreInfo open_store(const std::string& path);
// A multiscale group (or bare array) at `dir` inside store `path`.
Multiscale open_multiscale(const std::filesystem::path& dir, const std::string& path, const std::string& what);

// True when `path` names a Zarr store: it ends in .zarr (optionally with a trailing slash) or is a
// directory holding .zattrs/.zgroup/.zarray or (v3) zarr.json.
bool is_zarr_path(const std::string& path);

// "level 2 (array 'labels/cells/2')" for messages.
std::string level_name(const Multiscale& m, int level);

}  // namespace sl::zarr
