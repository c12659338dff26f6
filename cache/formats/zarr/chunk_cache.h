// A bounded cache of decoded chunks, shared by the chunked-store readers (Zarr's ArrayReader, array.h;
// Neuroglancer precomputed's VolumeReader) and their caches of decoded shard indices.
#pragma once

#include <cstddef>
#include <list>
#include <memory>
#include <mutex>
#include <string>
#include <unordered_map>
#include <vector>

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

// Default chunk-cache bound of a chunked-store source (ZarrVolumeSource, PrecomputedVolumeSource): big
// enough for the chunks a few loader threads touch at once plus neighbours (aprons), small next to the
// brick cache.
inline constexpr std::size_t kDefaultChunkCacheBytes = std::size_t(256) << 20;
// Bound of a reader's cache of decoded shard indices (Zarr v3 shard indices, precomputed minishard
// indices), kept apart from the chunks so that neither a chunk-free reader (the in-core load) nor a
// stream of chunks re-reads an index per inner chunk: 64 MiB holds the indices of 4096 shards of 32³
// inner chunks.
inline constexpr std::size_t kShardIndexCacheBytes = std::size_t(64) << 20;

}  // namespace sl::zarr
