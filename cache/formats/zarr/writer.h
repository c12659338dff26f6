// Writing an OME-Zarr store (NGFF 0.4 on Zarr v2, or NGFF 0.5 on Zarr v3, optionally sharded): the root
// group with its multiscales metadata, one array per level ("0", "1", ...), and optionally an NGFF label
// image under labels/labels/, and optionally the max pyramid under max/ (levels 1, 2, ..., declared by
// the root's "sparseleap" attribute; docs/formats.md "Max levels"). Chunks are written slab by slab (a layer of chunks along z at a time);
// chunks that hold only the fill value (0) are not written, which Zarr readers take as the fill value
// (sparse data stay small). The writer creates the files but does not make the store appear:
// cache/formats/ingest.h writes into a temporary directory and renames it when complete. A sharded v3 level keeps the encoded inner chunks of one
// layer of shards (shard chunk layers) until the layer is complete, then writes each shard whole.
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "cache/formats/zarr/meta.h"

namespace sl::zarr {

struct WriterOptions {
  int chunk = 64;  // chunk edge (voxels) in x, y and z
  Compressor compressor;
  int levels = 1;
  std::optional<VoxelType> label_type;  // write labels/labels/ too
  int zarr_format = 2;                  // 2 (NGFF 0.4) or 3 (NGFF 0.5)
  int shard = 0;                        // v3: shard edge in chunks (0: unsharded)
  bool max_levels = false;              // write max/ too (when levels >= 2)
};

// The pyramids of a store: the image (mean), its labels (mode) and the image's max pyramid, which
// holds levels 1, 2, ... only (its level 0 is the image's).
enum class Target { Image, Labels, Max };

class StoreWriter {
 public:
  // Creates `dir` (which must not exist) with every metadata file. `who` is what errors name.
  StoreWriter(const std::filesystem::path& dir, std::string who, const VolumeDesc& desc, const WriterOptions& o);

  // Writes z-planes [z0, z0 + nz) of `level` of `target` (dims ceil(desc.dims / 2^level)), a dense x-fastest
  // slab in native byte order; z0 must be a multiple of the chunk edge and nz the chunk edge unless
  // the slab ends the level. Encodes and writes the chunk layer in parallel.
  void write_slab(Target target, int level, int z0, int nz, const std::byte* data);
  // True when the store gets a max pyramid (WriterOptions::max_levels and at least two levels).
  bool has_max_levels() const { return o_.max_levels && o_.levels >= 2; }

  // Records the largest label id in the label image's attributes (read back by ZarrVolumeSource).
  void set_max_label(std::uint32_t max_label);

  std::uint64_t bytes_written() const { return bytes_written_.load(); }
  ivec3 level_dims(int level) const;
  const WriterOptions& options() const { return o_; }

 private:
  void write_file(const std::filesystem::path& p, const void* data, std::size_t n) const;
  void write_group(const std::filesystem::path& group, const std::string& name, Target target) const;
  std::filesystem::path array_dir(Target target, int level) const;
  void write_json(const std::filesystem::path& p, const std::string& text) const;
  std::filesystem::path attrs_file(const std::filesystem::path& group) const;

  std::filesystem::path dir_;
  std::string who_;
  VolumeDesc desc_;
  WriterOptions o_;
  mutable std::atomic<std::uint64_t> bytes_written_{0};
  // Sharded v3: per (target, level), the encoded inner chunks of the current layer of shards, indexed
  // [shard (y, x)][inner chunk (z, y, x)].
  std::map<std::pair<Target, int>, std::vector<std::vector<std::optional<std::vector<std::byte>>>>> pending_;
};

}  // namespace sl::zarr
