// A ByteStore decorator counting the requests and bytes that pass through it (whole objects, ranges and
// suffixes alike), so a render can report what it read from a store (bench's `store` line), whatever the
// store is (a local directory, HTTP). Thread-safe: relaxed atomics, read after the loaders are idle.
#pragma once

#include <atomic>
#include <memory>

#include "cache/stores/byte_store.h"

namespace sl {

class CountingByteStore final : public ByteStore {
 public:
  explicit CountingByteStore(std::shared_ptr<const ByteStore> inner) : inner_(std::move(inner)) {}

  std::optional<std::vector<std::byte>> read(const std::string& key, std::uint64_t max_bytes) const override {
    return count(inner_->read(key, max_bytes));
  }
  std::optional<std::vector<std::byte>> read_range(const std::string& key, std::uint64_t offset,
                                                   std::uint64_t n) const override {
    return count(inner_->read_range(key, offset, n));
  }
  std::optional<std::vector<std::byte>> read_suffix(const std::string& key, std::uint64_t n) const override {
    return count(inner_->read_suffix(key, n));
  }

  // Requests answered (found or not) and bytes returned so far.
  std::uint64_t requests() const { return requests_.load(std::memory_order_relaxed); }
  std::uint64_t bytes() const { return bytes_.load(std::memory_order_relaxed); }

 private:
  std::optional<std::vector<std::byte>> count(std::optional<std::vector<std::byte>> r) const {
    requests_.fetch_add(1, std::memory_order_relaxed);
    if (r) bytes_.fetch_add(r->size(), std::memory_order_relaxed);
    return r;
  }

  std::shared_ptr<const ByteStore> inner_;
  mutable std::atomic<std::uint64_t> requests_{0}, bytes_{0};
};

}  // namespace sl
