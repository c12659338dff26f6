#include "cache/formats/zarr/chunk_cache.h"

namespace sl::zarr {

ChunkCache::Chunk ChunkCache::get(const std::string& key) {
  std::lock_guard lock(mutex_);
  const auto it = index_.find(key);
  if (it == index_.end()) return nullptr;
  lru_.splice(lru_.begin(), lru_, it->second);
  return it->second->chunk;
}

void ChunkCache::put(const std::string& key, Chunk chunk) {
  const std::size_t size = chunk->size();
  if (size > max_bytes_) return;
  std::lock_guard lock(mutex_);
  insert_locked(key, std::move(chunk), size);
}

void ChunkCache::put_missing(const std::string& key, Chunk fill) {
  const std::size_t charge = key.size() + 64;  // the entry, not the shared chunk
  if (charge > max_bytes_) return;
  std::lock_guard lock(mutex_);
  insert_locked(key, std::move(fill), charge);
}

void ChunkCache::insert_locked(const std::string& key, Chunk chunk, std::size_t charge) {
  if (index_.count(key)) return;  // another thread decoded it too
  lru_.push_front({key, std::move(chunk), charge});
  index_[key] = lru_.begin();
  bytes_ += charge;
  while (bytes_ > max_bytes_) {
    bytes_ -= lru_.back().charge;
    index_.erase(lru_.back().key);
    lru_.pop_back();
  }
}

std::size_t ChunkCache::bytes() const {
  std::lock_guard lock(mutex_);
  return bytes_;
}

}  // namespace sl::zarr
