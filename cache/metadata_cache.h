// The out-of-core renderer's block metadata (DESIGN.md "Virtual memory"), kept in bounded memory: each
// culling block's min/max and label list is computed once, when its brick is first loaded (or bound
// by the source), and reused to regrow retired tree regions and to re-cull after a transfer-function
// or label change without touching the data. Left unbounded, a long exploration keeps the metadata of
// every block it ever saw; here the least recently used blocks beyond a capacity are dropped. A block
// whose metadata was dropped is UNKNOWN again when the tree next needs it: its rays report occupancy
// misses and the brick is read once more for it — never a wrong cull.
#pragma once

#include <cstddef>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include "core/occupancy/block_metadata.h"

namespace sl {

class MetadataCache {
 public:
  // capacity: blocks kept at most once eviction has run (a soft bound: the blocks used in the last
  // two frames are never dropped, so a view needing more than the capacity keeps them all).
  explicit MetadataCache(std::size_t capacity) : capacity_(capacity) {}

  std::size_t size() const { return entries_.size(); }
  std::size_t capacity() const { return capacity_; }
  bool contains(std::uint64_t key) const { return entries_.count(key) != 0; }
  // The block's metadata, null if not cached; `frame` marks it used.
  const BlockMetadata* find(std::uint64_t key, std::uint32_t frame);
  // As find, for a key known to be cached.
  const BlockMetadata& at(std::uint64_t key, std::uint32_t frame);
  // Without marking it used (re-culling reads every entry, which says nothing of what is in view).
  const BlockMetadata& peek(std::uint64_t key) const { return entries_.at(key).m; }
  void put(std::uint64_t key, BlockMetadata m, std::uint32_t frame);
  void touch(std::uint64_t key, std::uint32_t frame);

  // Drops the least recently used blocks, not used since frame - 1, down to 7/8 of the capacity
  // (amortised: runs only once the capacity is exceeded). Returns the keys dropped.
  std::vector<std::uint64_t> evict(std::uint32_t frame);
  // Blocks dropped since the cache was made.
  std::uint64_t evictions() const { return evictions_; }
  // Bytes held: entries, label lists and the hash table's buckets (an estimate of the heap in use).
  std::size_t memory_bytes() const;

  template <class Fn>
  void for_each(Fn&& fn) const {  // fn(key, const BlockMetadata&), in no particular order
    for (const auto& [key, e] : entries_) fn(key, e.m);
  }

 private:
  struct Entry {
    BlockMetadata m;
    std::uint32_t used = 0;  // frame of the last use
  };
  std::unordered_map<std::uint64_t, Entry> entries_;
  std::size_t capacity_;
  std::size_t label_ids_ = 0;  // label ids held by all entries' lists
  std::uint64_t evictions_ = 0;
};

}  // namespace sl
