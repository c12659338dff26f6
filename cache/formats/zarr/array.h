// Reading voxels of one OME-Zarr multiscale image (meta.h) chunk by chunk, through a small
// host-side cache of decoded chunks. Used by ZarrVolumeSource (bricks for the loader's worker
// threads) and by the in-core load of a whole level.
#pragma once

#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "cache/formats/zarr/chunk_cache.h"
#include "cache/formats/zarr/meta.h"
#include "cache/stores/byte_store.h"

namespace sl::zarr {

class ArrayReader {
 public:
  // `store` is the path errors name; cache may be shared between readers (keys include the array).
  ArrayReader(Multiscale m, std::string store, std::shared_ptr<ChunkCache> cache);

  const Multiscale& multiscale() const { return m_; }
  int levels() const { return int(m_.levels.size()); }
  VoxelType type() const { return m_.desc.type; }

  // Fills `dst` (n voxels, x fastest, native byte order) with level voxels [first, first + n),
  // each coordinate clamped to the stored shape (so a floor-halved level reads like a ceil-halved
  // one with its last voxel repeated). Missing chunk files read as the fill value. Thread-safe.
  // Throws InputError(store, "level L (array 'P') chunk K: reason") for unreadable or bad chunks, a
  // TransientError (same text) when the store's failure may not recur (HTTP 5xx, timeout).
  void read_box(int level, ivec3 first, ivec3 n, std::byte* dst) const;

  // The decoded chunk (cx, cy, cz) of a level: chunk_bytes() bytes, native order.
  ChunkCache::Chunk chunk(int level, ivec3 c) const;

 private:
  // Zarr v3: chunk c of the read grid (an inner chunk when sharded; v3_chunk.h).
  ChunkCache::Chunk chunk_v3(int level, ivec3 c) const;
  // Key prefix of a level's array in the store: "" or ending in '/'.
  std::string array_dir(int level) const;

  Multiscale m_;
  std::string store_;
  std::shared_ptr<ChunkCache> cache_;
  std::shared_ptr<ChunkCache> index_cache_;     // v3 shard indices
  std::vector<ChunkCache::Chunk> fill_;  // per level: a chunk of the fill value
};

}  // namespace sl::zarr
