// OME-Zarr (NGFF 0.4) on Zarr v2 and (NGFF 0.5) on Zarr v3: the metadata of a store. A store is a key space
// read through a ByteStore (a local directory or an HTTP(S) URL, cache/stores/store_url.h); its root group's
// .zattrs "multiscales" names one array per level (datasets[].path) with per-level scale transforms,
// and an optional "labels" group holds label images with their own multiscales (NGFF's image-label).
// A bare Zarr v2 array (a directory with .zarray) is read as a one-level store. Zarr v3 (zarr.json,
// v3_array.h) has the same layout with "multiscales" and "labels" under the group's attributes.ome.
//
// Mapping to sparseleap's volume (DESIGN.md "Data model"): the last three array axes are z, y, x; zarr's C
// order makes x fastest, exactly as Volume stores it. Leading axes (t, c) must have size 1. Each level
// must halve the previous one in x, y and z (ceil or floor of an odd size); other pyramids are refused
// with a clear message rather than resampled.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cache/formats/zarr/compressor.h"
#include "cache/stores/byte_store.h"
#include "core/scene/volume.h"
#include "core/util/math.h"

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
  // Zarr v3 only: codecs, chunk keys and shards (v3_codec.h); `chunks` is then the read grid (the
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

// Largest decoded chunk accepted (of the read grid: an inner chunk when sharded): bigger chunks would
// make every brick read slow and the cache useless.
inline constexpr std::uint64_t kMaxChunkBytes = std::uint64_t(1) << 30;

struct Level {
  std::string path;  // relative to the multiscale group
  ArrayMeta meta;
  ivec3 dims{0};
  vec3 scale{1.0f};  // voxel size (x, y, z) from coordinateTransformations; 1 when absent
};

struct Multiscale {
  std::shared_ptr<const ByteStore> bytes;  // the store's root
  std::string prefix;         // key prefix of the group holding the level arrays: "" or "labels/NAME/"
  std::string what;           // "" for the image, "labels/NAME" for a label image (for messages)
  std::vector<Level> levels;
  VolumeDesc desc;            // level 0: dims, spacing (level-0 scale), type
};

struct StoreInfo {
  std::string path;                     // as the user gave it (errors name it)
  Multiscale image;
  std::optional<Multiscale> labels;     // the first entry of labels/.zattrs "labels", if any
  std::vector<std::string> label_names; // every entry
  // The max pyramid beside the mean one (docs/formats.md "Max levels"): levels 1, 2, ... of the image
  // reduced by max, as the multiscale group the root's "sparseleap": {"max_pyramid": GROUP} names.
  std::optional<Multiscale> max;
};

// Reads and checks all metadata of the store whose root is `bytes` (no chunk data). Every problem
// throws InputError(name, reason) naming the level and array at fault; a TransientError of the store
// (an HTTP 5xx, a timeout) stays one.
StoreInfo open_store(std::shared_ptr<const ByteStore> bytes, const std::string& name);
// The store at `path`: a local directory, or a URL (http://, https://, zarr://, zarr2://, zarr3://;
// cache/stores/store_url.h). Errors name `path` as given.
StoreInfo open_store(const std::string& path);
// A multiscale group (or bare array) at key prefix `prefix` ("" or ending in '/') of store `name`.
Multiscale open_multiscale(std::shared_ptr<const ByteStore> bytes, const std::string& prefix, const std::string& name,
                           const std::string& what);

// `prefix` + `key`, where a key of "." (a bare array is its own level) adds nothing, so that local
// paths and URLs never hold a "./" segment.
std::string join_key(const std::string& prefix, const std::string& key);

// "level 2 (array 'labels/cells/2')" for messages.
std::string level_name(const Multiscale& m, int level);

}  // namespace sl::zarr
