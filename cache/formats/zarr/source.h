// ZarrVolumeSource: an OME-Zarr store (meta.h) behind the VolumeSource interface (DESIGN.md "Data
// model"), read lazily, chunk by chunk, so a store far larger than memory renders out of core
// (DESIGN.md "Virtual memory").
//
// Bricks are cut from whatever chunks overlap them (chunk shape need not equal the brick size), aprons
// included. Levels the store lacks (the brick pyramid continues until one brick holds the volume) are
// derived at construction from the coarsest stored level by the same 2x reductions MemoryVolumeSource
// uses (cache/pyramid.h: mean for intensity, mode for labels) and kept in memory; this needs the coarsest
// stored level to be at most kMaxDerivedBaseBytes (cache/formats/chunked_levels.h; stores written by
// `sparseleap ingest` end at one chunk). The max pyramid (PyramidKind::Max) reads the store's max levels
// (meta.h StoreInfo::max) and derives the ones past them by reduce_max the same way; a store of one
// level derives all of them. Labels come from the store's NGFF labels/ group (its first label image) or from a separate
// store given by path (its image array).
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cache/formats/zarr/array.h"
#include "cache/volume_source.h"

namespace sl {

class ZarrVolumeSource final : public VolumeSource {
 public:
  // Opens `path` and, when `labels_path` is not empty, that store's image as the labels (replacing the
  // store's own labels/ group). `pyramid`: the intensity pyramid to serve; nullopt = max when the
  // store has max levels, mean otherwise (`--pyramid`'s default). Throws InputError for bad metadata, a coarsest level too large, or
  // Max asked of a store without max levels.
  explicit ZarrVolumeSource(const std::string& path, const std::string& labels_path = "",
                            std::optional<PyramidKind> pyramid = PyramidKind::Mean,
                            std::size_t chunk_cache_bytes = zarr::kDefaultChunkCacheBytes);

  const VolumeDesc& desc() const override { return image_->multiscale().desc; }
  bool has_labels() const override { return labels_ != nullptr; }
  VoxelType label_type() const override { return labels_ ? labels_->type() : VoxelType::U32; }
  const std::string& name() const override { return name_; }
  // Throws InputError(store, "level L (array 'P') chunk K: reason") for a bad chunk.
  void read_brick(const BrickLayout& layout, BrickId id, std::span<std::byte> out_intensity,
                  std::span<std::byte> out_labels) const override;

  PyramidKind pyramid() const override { return pyramid_; }
  int stored_levels() const { return image_->levels(); }
  // Levels 1, 2, ... stored in the store's max pyramid (0 without one).
  int stored_max_levels() const { return max_ ? max_->levels() : 0; }
  const zarr::ChunkCache& chunk_cache() const { return *cache_; }
  // Largest label id: the store's "sparseleap" attribute when `ingest` wrote it; otherwise a scan of
  // the finest stored label level of at most 256 MiB (exact when that is level 0). 0 without labels.
  // A chunk the scan cannot read counts as empty: it takes the out-of-core fault path when a brick
  // needs it (reported there, rendered as missing), instead of stopping the render before it starts.
  std::uint32_t max_label() const;
  // Value range of the finest stored level of at most 64 MiB (for a default transfer function; the
  // coarse levels' means narrow the range a little).
  vec2 value_range_estimate() const;

 private:
  std::string name_;
  std::shared_ptr<zarr::ChunkCache> cache_;
  std::unique_ptr<zarr::ArrayReader> image_, labels_, max_;
  PyramidKind pyramid_ = PyramidKind::Mean;
  std::uint32_t max_label_attr_ = 0;
  bool has_max_label_attr_ = false;
  // Levels past the stored ones: stored_levels() + i for the mean pyramid and labels, 1 +
  // stored_max_levels() + i for the max pyramid (derived_ holds the served intensity pyramid's).
  std::vector<Volume> derived_, derived_labels_;
};

// The whole of level 0 of a store's image (or of its first label image), for in-core rendering.
// Checked against validate_desc's memory limit first. Throws InputError naming the store.
Volume read_zarr_volume(const std::string& path, bool labels = false);

}  // namespace sl
