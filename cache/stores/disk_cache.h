// An optional on-disk cache of remote store objects (`--disk-cache DIR --disk-cache-mb N`):
// a second run over the same URL reads chunks, shard indices and metadata from the local disk instead
// of the network.
//
// Ownership: the cache deletes files, so it only ever touches what it wrote. DIR holds its marker file
// `.sparseleap-disk-cache` (a fixed first line) and its subfolder `entries/`; every entry and every
// temporary lives in `entries/`. A new or empty DIR is made a cache (marker, then subfolder); a DIR with
// the marker is re-adopted; any other non-empty DIR is refused, so pointing `--disk-cache` at a folder
// of one's own files cannot lose them. Inside `entries/` only regular files named as the cache names
// them are indexed (entries carry the cache's magic too); symlinks and other files are never followed,
// read or deleted.
//
// One file per object (or byte range), named by a 64-bit hash of its key (URL + range). A file holds a
// header (magic, key and payload lengths, CRC-32 of key + payload), the key, then the payload; it is
// written under a temporary name and renamed into place, so a crash mid-write leaves at worst a
// temporary file (removed at the next start), never a half-written entry under a real name. An entry
// that is short or fails its checksum (a torn disk) is dropped and refetched.
// Least recently used files are deleted once the total passes the byte bound; the order is kept in
// memory and rebuilt from the files' modification times (touched on every hit) by scanning at start.
#pragma once

#include <atomic>
#include <cstdint>
#include <list>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "cache/stores/byte_store.h"

namespace sl {

struct DiskCacheCounters {
  std::atomic<std::uint64_t> hits{0}, misses{0}, corrupt{0}, evicted{0}, write_failures{0};
};

class DiskCache {
 public:
  static constexpr const char* kMarkerName = ".sparseleap-disk-cache";  // in DIR: it is a cache
  static constexpr const char* kEntriesName = "entries";                // in DIR: everything it stores

  // Creates or re-adopts the cache in `dir` (see above) and indexes its entries. Throws
  // InputError("--disk-cache", "<dir>: why") when `dir` is not a directory, cannot be made, written or
  // read, or holds files and is not a cache.
  DiskCache(std::string dir, std::uint64_t max_bytes);

  // The payload stored under `key`, or nullopt (a miss, or a bad file, which is deleted).
  std::optional<std::vector<std::byte>> get(const std::string& key);
  // Stores a payload (skipped when larger than the bound; a failed write only loses the entry).
  void put(const std::string& key, const std::vector<std::byte>& payload);

  std::uint64_t bytes() const;
  std::uint64_t max_bytes() const { return max_bytes_; }
  std::size_t files() const;
  const std::string& dir() const { return dir_; }
  const DiskCacheCounters& counters() const { return counters_; }

 private:
  struct Entry {
    std::list<std::string>::iterator lru;
    std::uint64_t size = 0;  // file bytes
  };
  std::string path(const std::string& name) const { return entries_ + "/" + name; }
  void adopt();  // makes `dir_` a cache or checks that it is one
  void scan();   // indexes the entries, removes the temporaries a crash left
  // Deletes an entry file when it is still a regular file (never a symlink put in its place).
  void remove_entry_file(const std::string& name) const;
  void insert_locked(const std::string& name, std::uint64_t size);  // front of the LRU, then evict
  void erase_locked(const std::string& name);

  std::string dir_;
  std::string entries_;  // dir_ + "/entries"
  std::uint64_t max_bytes_;
  mutable std::mutex mutex_;
  std::list<std::string> lru_;  // front: most recently used
  std::unordered_map<std::string, Entry> index_;
  std::uint64_t bytes_ = 0;
  std::atomic<std::uint64_t> tmp_serial_{0};
  DiskCacheCounters counters_;
};

// A ByteStore read through a DiskCache: objects and ranges of `inner` are looked up under
// `name` (the store's URL) + key (+ range) first. Missing objects are not cached (a 404 is cheap).
class CachedByteStore final : public ByteStore {
 public:
  CachedByteStore(std::shared_ptr<const ByteStore> inner, std::string name, std::shared_ptr<DiskCache> cache)
      : inner_(std::move(inner)), name_(std::move(name)), cache_(std::move(cache)) {}

  std::optional<std::vector<std::byte>> read(const std::string& key, std::uint64_t max_bytes) const override;
  std::optional<std::vector<std::byte>> read_range(const std::string& key, std::uint64_t offset,
                                                   std::uint64_t n) const override;
  std::optional<std::vector<std::byte>> read_suffix(const std::string& key, std::uint64_t n) const override;

 private:
  template <class Fetch>
  std::optional<std::vector<std::byte>> through(const std::string& cache_key, Fetch fetch) const;

  std::shared_ptr<const ByteStore> inner_;
  std::string name_;
  std::shared_ptr<DiskCache> cache_;
};

}  // namespace sl
