// `sparseleap ingest`: converting a volume file (NRRD, a TIFF stack, NIfTI; volume_file.h) into an
// OME-Zarr store (zarr/writer.h) with the full 2x pyramid of DESIGN.md "Data model" and the max pyramid
// beside it (pyramid.h PyramidKind), slab by slab, so memory stays bounded however deep the input is.
//
// The input is read one chunk layer (chunk-edge z-planes) at a time. Level l keeps one layer buffer of
// its own; a full layer is written as chunks and reduced 2x into the next level's buffer (which fills
// after two such layers). Peak memory is therefore about
//   (4/3) * chunk * X * Y * bytes_per_voxel      (+ the same for labels, with their voxel size)
// plus (1/3) * chunk * X * Y * bytes_per_voxel for the max pyramid's levels >= 1 and one chunk per
// worker thread for encoding: memory_bound() computes it. It depends on the slice size X * Y and the
// chunk edge, never on the depth Z.
// Levels continue until one chunk holds the level; readers derive coarser ones (zarr/source.h).
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "cache/formats/slab_reader.h"
#include "cache/formats/zarr/compressor.h"
#include "core/scene/volume.h"

namespace sl {

struct IngestOptions {
  int chunk = 64;                     // chunk edge; even, 8-512
  zarr::Compressor compressor = zarr::compressor_from_name("blosc-zstd");
  std::string labels;                 // optional label volume (same dims, integer type)
  bool force = false;                 // replace an existing OUT
  // Refused up front (naming IN and the size) when memory_bound() exceeds this; 0: no limit.
  std::uint64_t max_memory = 0;
  int zarr_format = 2;                // 2: NGFF 0.4 on Zarr v2; 3: NGFF 0.5 on Zarr v3
  int shard = 0;                      // Zarr v3: shards of shard³ chunks (0: unsharded)
  // Called after every input slab with input bytes read so far and in total (intensity + labels).
  std::function<void(std::uint64_t done, std::uint64_t total)> progress;
};

struct IngestResult {
  VolumeDesc desc;
  int levels = 0;
  std::uint64_t input_bytes = 0;   // voxel bytes read (intensity + labels)
  std::uint64_t stored_bytes = 0;  // bytes written into the store (chunks and metadata)
  std::uint64_t memory_bound = 0;  // memory_bound() for this input
  std::uint32_t max_label = 0;
};

// Pyramid levels the store gets: level 0 and halvings until one chunk holds the level.
int ingest_levels(ivec3 dims, int chunk);
// Bytes of the layer buffers (see the header comment) plus one encode chunk per thread; with shards of
// shard³ chunks, plus the encoded chunks of one layer of shards (counted at their raw size).
std::uint64_t memory_bound(const VolumeDesc& d, std::optional<VoxelType> label_type, int chunk, int shard = 0);

// Writes `out` under a hidden temporary name beside it and renames it only when complete; any failure
// removes the temporary directory and throws InputError. `out` must not exist unless o.force.
IngestResult ingest(const std::string& in, const std::string& out, const IngestOptions& o);

}  // namespace sl
