// The unified miss buffer (paper §8.2, "Simplified implementation"): during a frame the caster
// appends brick ids — one kind of miss for both occupancy and data — to a bounded, de-duplicated set;
// the host then decides per id what the miss means. Many rays hit the same brick, so de-duplication
// happens at insert time: an open-addressing hash table claimed with CAS, and a compact append array
// the host drains. Plain data on the device side; no std:: containers in SL_HOST_DEVICE code.
#pragma once

#include <cstdint>
#include <vector>

#if !defined(__CUDA_ARCH__)
#include <atomic>
#endif

#include "cache/brick.h"
#include "core/util/config.h"

namespace sl {

// Table slots hold id.bits + 1 so that all-zero memory is an empty table (cudaMemset/fill 0); the
// all-ones id is never valid (level 15 is reserved), so + 1 cannot wrap to 0.
struct MissBufferView {
  std::uint64_t* table = nullptr;     // table_mask + 1 slots (a power of two, >= 2 x capacity)
  std::uint64_t* list = nullptr;      // capacity ids in insertion order
  std::uint32_t* counters = nullptr;  // [0] ids claimed (may exceed capacity), [1] dropped inserts
  std::uint32_t table_mask = 0;
  std::uint32_t capacity = 0;

  // Adds id unless present. Returns true when this call added it to the list. An insert finding the
  // list (or, past 2 x capacity distinct ids, the table) full is counted in counters[1] and lost:
  // the host sees the overflow and the ray reports the brick again next frame.
  SL_HOST_DEVICE bool insert(BrickId id) const {
    const std::uint64_t key = id.bits + 1;
    std::uint32_t i = home(id.bits, table_mask);
    for (std::uint32_t probe = 0; probe <= table_mask; ++probe, i = (i + 1) & table_mask) {
      std::uint64_t seen = load(table + i);
      if (seen == key) return false;
      if (seen == 0) {
        seen = cas(table + i, key);
        if (seen == 0) {  // claimed: this thread appends
          const std::uint32_t n = add(counters + 0);
          if (n < capacity) {
            list[n] = id.bits;
            return true;
          }
          add(counters + 1);
          return false;
        }
        if (seen == key) return false;  // another thread claimed it for the same id
      }
    }
    add(counters + 1);  // table full
    return false;
  }

  // First table slot probed for an id (Fibonacci hashing; bricks of a ray are near in id space).
  SL_HOST_DEVICE static std::uint32_t home(std::uint64_t bits, std::uint32_t mask) {
    const std::uint64_t h = bits * 0x9E3779B97F4A7C15ull;
    return std::uint32_t(h >> 32) & mask;
  }

 private:
  SL_HOST_DEVICE static std::uint64_t load(std::uint64_t* p) {
#if defined(__CUDA_ARCH__)
    return *reinterpret_cast<volatile unsigned long long*>(p);
#else
    return std::atomic_ref<std::uint64_t>(*p).load(std::memory_order_relaxed);
#endif
  }
  // Compare-and-swap 0 -> key; returns the value found (0 on success).
  SL_HOST_DEVICE static std::uint64_t cas(std::uint64_t* p, std::uint64_t key) {
#if defined(__CUDA_ARCH__)
    return atomicCAS(reinterpret_cast<unsigned long long*>(p), 0ull, (unsigned long long)key);
#else
    std::uint64_t expected = 0;
    std::atomic_ref<std::uint64_t>(*p).compare_exchange_strong(expected, key, std::memory_order_relaxed);
    return expected;
#endif
  }
  SL_HOST_DEVICE static std::uint32_t add(std::uint32_t* p) {
#if defined(__CUDA_ARCH__)
    return atomicAdd(reinterpret_cast<unsigned int*>(p), 1u);
#else
    return std::atomic_ref<std::uint32_t>(*p).fetch_add(1u, std::memory_order_relaxed);
#endif
  }
};
static_assert(sizeof(MissBufferView) == 32, "MissBufferView is plain data");

// Host owner. Use: clear() before a frame, casters insert through view() (from any thread), then
// drain() after the frame's parallel loop has joined (the join orders the relaxed writes).
class MissBuffer {
 public:
  explicit MissBuffer(std::uint32_t capacity = 1u << 16);

  MissBufferView view();
  // The distinct ids inserted this frame (at most capacity), sorted so resolution is deterministic.
  std::vector<BrickId> drain() const;
  void clear();

  std::uint32_t capacity() const { return capacity_; }
  std::uint32_t size() const;            // ids in the list
  std::uint32_t dropped() const;         // inserts lost to overflow this frame
  bool overflowed() const { return dropped() > 0; }

 private:
  std::uint32_t capacity_;
  std::vector<std::uint64_t> table_;
  std::vector<std::uint64_t> list_;
  std::vector<std::uint32_t> counters_;
};

}  // namespace sl
