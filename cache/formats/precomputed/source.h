// PrecomputedVolumeSource: a Neuroglancer precomputed volume (precomputed_info.h), and optionally a
// second one holding its segmentation labels, behind the VolumeSource interface (DESIGN.md "Data model"), read
// lazily chunk by chunk through a ByteStore (a local directory, or HTTP), so a volume far larger than
// memory renders out of core (DESIGN.md "Virtual memory"). Unsharded chunks are objects
// "KEY/x0-x1_y0-y1_z0-z1"; sharded ones are fetched by byte range from their shard (precomputed_shard.h).
// A chunk that is not stored reads as zeros. Decoded chunks go through a zarr::ChunkCache, and the
// levels the volume lacks below its coarsest scale are derived as ZarrVolumeSource derives them
// (chunked_levels.h).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "cache/formats/precomputed/info.h"
#include "cache/formats/zarr/chunk_cache.h"
#include "cache/stores/byte_store.h"
#include "cache/volume_source.h"

namespace sl {

namespace precomputed {

// One precomputed volume: its info, and voxels of any box of any scale.
class VolumeReader {
 public:
  // Reads and checks `info`. Throws InputError(name, ...) when it is missing or bad.
  VolumeReader(std::shared_ptr<const ByteStore> bytes, std::string name, std::shared_ptr<zarr::ChunkCache> cache);

  const Info& info() const { return info_; }
  const std::string& name() const { return name_; }
  int levels() const { return int(info_.scales.size()); }
  VoxelType type() const { return info_.voxel_type(); }
  // Level `level`'s dims, type and spacing (level-0 resolution times 2^level, as the levels halve).
  VolumeDesc level_desc(int level) const;

  // Fills dst (n voxels, x fastest) with level voxels [first, first + n), each coordinate clamped to the
  // scale's size. Thread-safe. Throws InputError(name, "scale 'K' (level L) chunk C: reason"), a
  // TransientError when the store's failure was one.
  void read_box(int level, ivec3 first, ivec3 n, std::byte* dst) const;

 private:
  // The stored bytes of chunk c (through its shard when sharded), nullopt when it is not stored.
  std::optional<std::vector<std::byte>> chunk_data(int level, ivec3 c) const;
  zarr::ChunkCache::Chunk chunk(int level, ivec3 c) const;  // decoded; null when not stored (zeros)
  std::string chunk_name(int level, ivec3 c) const;          // for messages

  std::shared_ptr<const ByteStore> bytes_;
  std::string name_;
  Info info_;
  std::shared_ptr<zarr::ChunkCache> cache_, index_cache_;  // decoded chunks; decoded minishard indices
};

}  // namespace precomputed

class PrecomputedVolumeSource final : public VolumeSource {
 public:
  // `bytes` holds the image volume (its `info` at the root); `labels_bytes`, when not null, a
  // segmentation volume of the same size. Names are what errors say. Throws InputError for bad info,
  // label dims that differ, a float label volume, or a coarsest scale too large to derive levels from.
  PrecomputedVolumeSource(std::shared_ptr<const ByteStore> bytes, std::string name,
                          std::shared_ptr<const ByteStore> labels_bytes = nullptr, std::string labels_name = "",
                          std::size_t chunk_cache_bytes = zarr::kDefaultChunkCacheBytes);

  const VolumeDesc& desc() const override { return desc_; }
  bool has_labels() const override { return labels_ != nullptr; }
  VoxelType label_type() const override { return labels_ ? labels_->type() : VoxelType::U32; }
  const std::string& name() const override { return image_->name(); }
  void read_brick(const BrickLayout& layout, BrickId id, std::span<std::byte> out_intensity,
                  std::span<std::byte> out_labels) const override;

  int stored_levels() const { return image_->levels(); }
  const precomputed::VolumeReader& image() const { return *image_; }
  const precomputed::VolumeReader* labels() const { return labels_.get(); }
  // Largest label id: a scan of the finest label scale of at most 256 MiB (unreadable chunks count as
  // empty, as ZarrVolumeSource::max_label does). 0 without labels.
  std::uint32_t max_label() const;
  // Value range of the finest scale of at most 64 MiB (for a default transfer function).
  vec2 value_range_estimate() const;

 private:
  VolumeDesc desc_;
  std::shared_ptr<zarr::ChunkCache> cache_;
  std::unique_ptr<precomputed::VolumeReader> image_, labels_;
  std::vector<Volume> derived_, derived_labels_;  // levels stored_levels() + i
};

// A local directory as a ByteStore (the convenience opener): the source of `dir`, labels from
// `labels_dir` when not empty.
std::shared_ptr<PrecomputedVolumeSource> open_precomputed(const std::string& dir, const std::string& labels_dir = "");

// Level 0's dims, type and spacing (the `info` alone) of the precomputed volume in `dir`. InputError.
VolumeDesc read_precomputed_desc(const std::string& dir);

// The whole of level 0 of the precomputed volume in `dir`, for in-core rendering (checked against
// validate_desc's memory limit first). Throws InputError naming the volume.
Volume read_precomputed_volume(const std::string& dir);

}  // namespace sl
