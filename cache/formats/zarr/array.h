// Reading voxels of one OME-Zarr multiscale image (zarr_meta.h) chunk by chunk, through a small
// host-side cache of decoded chunks. Used by ZarrVolumeSource (bricks for the loader's worker
// threads) and by the in-core load of a whole level.
#pragma once

#include <cstddef>
#include <list>
#include <memory>
#include <mutex>
#include <string>
#include <unordered_map>
#include <vector>

#include "cache/formats/zarr/meta.h"
#include "cache/stores/byte_store.h"

namespace sl::zarr {

// Decoded chunks (native byte order), least recently used evicted first once their total exceeds
// the byte bound (a single chunk larger than the bound is returned but not kept). Thread-safe: one
// mutex around the map; decoding happens outside it, so two threads missing the same chunk at once
// may both decode it (harmless, and rarer than the lock traffic a per-key wait would add).
class ChunkCache {
 public:
  using Chunk = std::shared_ptr<const std::vector<std::byte>>;
  explicit ChunkCache(std::size_t max_bytes) : max_bytes_(max_bytes) {}

  Chunk get(const std::string& key);
  void put(const std::string& key, Chunk chunk);
  // A chunk that is not stored (the shared fill-value chunk), remembered so that a remote store is
  // not asked again for an object it does not have; charged as a small entry, not as its data.
  void put_missing(const std::string& key, Chunk fill);
  std::size_t bytes() const;
  std::size_t max_bytes() const { return max_bytes_; }

 private:
  struct Entry {
    std::string key;
    Chunk chunk;
    std::size_t charge;  // bytes counted against the bound
  };
  void insert_locked(const std::string& key, Chunk chunk, std::size_t charge);
  const std::size_t max_bytes_;
  mutable std::mutex mutex_;
  std::list<Entry> lru_;  // front: most recently used
  std::unordered_map<std::string, std::list<Entry>::iterator> index_;
  std::size_t bytes_ = 0;
};

// Default chunk-cache bound of a ZarrVolumeSource: big enough for the chunks a few loader threads
// touch at once plus neighbours (aprons), small next to the brick cache.
inline constexpr std::size_t kDefaultChunkCacheBytes = std::size_t(256) << 20;
// Bound of an ArrayReader's cache of decoded shard indices (Zarr v3), kept apart from the chunks so
// that neither a chunk-free reader (the in-core load) nor a stream of chunks re-reads an index per
// inner chunk: 64 MiB holds the indices of 4096 shards of 32³ inner chunks.
inline constexpr std::size_t kShardIndexCacheBytes = std::size_t(64) << 20;

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
  // Zarr v3: chunk c of the read grid (an inner chunk when sharded) (zarr3_codec.h).
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
