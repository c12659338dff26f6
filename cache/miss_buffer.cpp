#include "cache/miss_buffer.h"

#include <algorithm>
#include <bit>

namespace sl {

MissBuffer::MissBuffer(std::uint32_t capacity) : capacity_(capacity) {
  SL_CHECK(capacity > 0 && capacity <= (1u << 30));
  // Twice the capacity keeps linear probing short (load factor <= 1/2 while the list has room).
  const std::uint32_t table_size = std::bit_ceil(2u * capacity);
  table_.assign(table_size, 0u);
  list_.assign(capacity, 0u);
  counters_.assign(2, 0u);
}

MissBufferView MissBuffer::view() {
  MissBufferView v;
  v.table = table_.data();
  v.list = list_.data();
  v.counters = counters_.data();
  v.table_mask = std::uint32_t(table_.size() - 1);
  v.capacity = capacity_;
  return v;
}

std::uint32_t MissBuffer::size() const { return std::min(counters_[0], capacity_); }
std::uint32_t MissBuffer::dropped() const { return counters_[1]; }

std::vector<BrickId> MissBuffer::drain() const {
  std::vector<BrickId> ids(size());
  for (std::size_t i = 0; i < ids.size(); ++i) ids[i].bits = list_[i];
  std::sort(ids.begin(), ids.end());
  return ids;
}

void MissBuffer::clear() {
  // Only the claimed table slots are non-zero; when few ids came in, clear just those.
  if (counters_[0] <= capacity_ && counters_[1] == 0) {
    const std::uint32_t mask = std::uint32_t(table_.size() - 1);
    for (std::uint32_t k = 0; k < counters_[0]; ++k) {
      const std::uint64_t key = list_[k] + 1;
      // Walk the probe chain past slots already cleared (zeros) until the key, which is present.
      for (std::uint32_t i = MissBufferView::home(list_[k], mask);; i = (i + 1) & mask) {
        if (table_[i] == key) {
          table_[i] = 0;
          break;
        }
      }
    }
  } else {
    std::fill(table_.begin(), table_.end(), 0u);
  }
  counters_[0] = counters_[1] = 0;
}

}  // namespace sl
