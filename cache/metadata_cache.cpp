#include "cache/metadata_cache.h"

#include <algorithm>

#include "core/util/config.h"

namespace sl {

const BlockMetadata* MetadataCache::find(std::uint64_t key, std::uint32_t frame) {
  const auto it = entries_.find(key);
  if (it == entries_.end()) return nullptr;
  it->second.used = std::max(it->second.used, frame);
  return &it->second.m;
}

const BlockMetadata& MetadataCache::at(std::uint64_t key, std::uint32_t frame) {
  const BlockMetadata* m = find(key, frame);
  SL_CHECK(m != nullptr);
  return *m;
}

void MetadataCache::put(std::uint64_t key, BlockMetadata m, std::uint32_t frame) {
  Entry& e = entries_[key];
  label_ids_ -= e.m.labels.size();
  label_ids_ += m.labels.size();
  e.m = std::move(m);
  e.used = std::max(e.used, frame);
}

void MetadataCache::touch(std::uint64_t key, std::uint32_t frame) {
  const auto it = entries_.find(key);
  if (it != entries_.end()) it->second.used = std::max(it->second.used, frame);
}

std::vector<std::uint64_t> MetadataCache::evict(std::uint32_t frame) {
  std::vector<std::uint64_t> dropped;
  if (entries_.size() <= capacity_) return dropped;
  const std::uint32_t recent = frame >= 1 ? frame - 1 : 0;
  std::vector<std::pair<std::uint32_t, std::uint64_t>> old;  // (last use, key), droppable
  old.reserve(entries_.size());
  for (const auto& [key, e] : entries_) {
    if (e.used < recent) old.emplace_back(e.used, key);
  }
  const std::size_t target = capacity_ - capacity_ / 8;
  const std::size_t excess = entries_.size() - std::min(entries_.size(), target);
  const std::size_t n = std::min(excess, old.size());
  if (n == 0) return dropped;
  // The n least recently used; ties by key, so the choice does not depend on the hash table's order.
  std::nth_element(old.begin(), old.begin() + std::ptrdiff_t(n - 1), old.end());
  dropped.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    const auto it = entries_.find(old[i].second);
    label_ids_ -= it->second.m.labels.size();
    entries_.erase(it);
    dropped.push_back(old[i].second);
  }
  evictions_ += n;
  return dropped;
}

std::size_t MetadataCache::memory_bytes() const {
  // A node of the hash table holds the key, the entry and the next pointer (plus the cached hash,
  // which libstdc++ omits for integer keys); each bucket is one pointer.
  const std::size_t node = sizeof(void*) + sizeof(std::uint64_t) + sizeof(Entry);
  return entries_.size() * node + entries_.bucket_count() * sizeof(void*) + label_ids_ * sizeof(std::uint32_t);
}

}  // namespace sl
