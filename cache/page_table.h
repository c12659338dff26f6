// Per-level two-level page table (DESIGN.md §4, after Hadwiger et al. 2012, the paper's [14]).
// A directory per level has one 32-bit entry per page-table page; each page holds the entries of
// 16³ bricks and is allocated from one pool only when an entry in it is first set, so a level of
// 30 million bricks costs memory only where rays went. Pointer-free inside: directory entries are
// page indices + 1 (0 = not allocated), pages live in one pool array.
#pragma once

#include <cstdint>
#include <cstring>
#include <vector>

#include "cache/brick.h"
#include "core/config.h"

namespace sl {

// One 32-bit page-table entry: 2-bit state in bits 30-31, payload in bits 0-29.
//  - Unmapped (0):  nothing known or not resident. All-zero bits, so a zeroed page reads Unmapped.
//  - Resident (1):  payload = brick cache slot (< 2^30).
//  - Empty (2):     every stored voxel (payload and apron) is 0 with label 0; nothing to sample.
//  - Constant (3):  every stored intensity voxel equals one value, labels are 0; payload = the raw
//                   value for integer types (< 2^30), or the f32 bit pattern >> 2 (see
//                   constant_encodable), so the caster needs no slot for a homogeneous brick.
struct PageEntry {
  enum class State : std::uint32_t { Unmapped = 0, Resident = 1, Empty = 2, Constant = 3 };
  static constexpr std::uint32_t kPayloadMask = (1u << 30) - 1;

  std::uint32_t bits = 0;

  SL_HOST_DEVICE static PageEntry unmapped() { return PageEntry{}; }
  SL_HOST_DEVICE static PageEntry resident(std::uint32_t slot) {
    return PageEntry{(std::uint32_t(State::Resident) << 30) | (slot & kPayloadMask)};
  }
  SL_HOST_DEVICE static PageEntry empty() { return PageEntry{std::uint32_t(State::Empty) << 30}; }
  SL_HOST_DEVICE static PageEntry constant_bits(std::uint32_t payload) {
    return PageEntry{(std::uint32_t(State::Constant) << 30) | (payload & kPayloadMask)};
  }

  SL_HOST_DEVICE State state() const { return State(bits >> 30); }
  SL_HOST_DEVICE bool is_resident() const { return state() == State::Resident; }
  SL_HOST_DEVICE std::uint32_t slot() const { return bits & kPayloadMask; }
  SL_HOST_DEVICE std::uint32_t payload() const { return bits & kPayloadMask; }
  // The constant's value as the caster samples it (raw integer, or f32).
  SL_HOST_DEVICE float constant_value(VoxelType t) const {
    if (t != VoxelType::F32) return float(payload());
    const std::uint32_t f = payload() << 2;
#if defined(__CUDA_ARCH__)
    return __int_as_float(int(f));
#else
    float v;
    std::memcpy(&v, &f, sizeof(v));
    return v;
#endif
  }

  SL_HOST_DEVICE friend bool operator==(PageEntry a, PageEntry b) { return a.bits == b.bits; }
};
static_assert(sizeof(PageEntry) == 4, "page-table entries are 32 bits");

// True when `value` of type t survives the Constant encoding exactly (integers < 2^30; floats whose
// two lowest mantissa bits are zero). Otherwise keep the brick Resident.
bool constant_encodable(float value, VoxelType t);
// Constant entry for `value`; requires constant_encodable(value, t).
PageEntry constant_entry(float value, VoxelType t);

inline constexpr int kPageBricks = 16;  // a page covers 16³ bricks
inline constexpr int kPageEntries = kPageBricks * kPageBricks * kPageBricks;

struct PageTableLevel {
  ivec3 pages{0};                  // page grid dims: ceil(bricks / 16)
  std::uint32_t directory_offset = 0;  // first directory entry of this level
};
static_assert(sizeof(PageTableLevel) == 16);

// What the caster reads: plain, two base pointers plus per-level geometry. Valid until the next
// PageTable::set that allocates a page (the pool may move) — build it once per frame.
struct PageTableView {
  const std::uint32_t* directory = nullptr;  // per level: page index + 1, or 0 (not allocated)
  const std::uint32_t* pool = nullptr;       // pages of kPageEntries entries each
  PageTableLevel level[kMaxBrickLevels];
  std::int32_t levels = 0;

  // Entry of brick `id`; a brick outside the level or on a page never allocated reads Unmapped.
  SL_HOST_DEVICE PageEntry lookup(BrickId id) const {
    const int l = id.level();
    if (l >= levels) return PageEntry::unmapped();
    const ivec3 p = id.coord() / kPageBricks;
    const PageTableLevel& L = level[l];
    if (p.x >= L.pages.x || p.y >= L.pages.y || p.z >= L.pages.z) return PageEntry::unmapped();
    const std::uint32_t dir = directory[directory_index(id)];
    if (dir == 0) return PageEntry::unmapped();
    return PageEntry{pool[pool_index(dir - 1, id)]};
  }

  // Word indices of a brick inside the level's page grid (a device mirror copies words by index).
  SL_HOST_DEVICE std::uint32_t directory_index(BrickId id) const {
    const ivec3 p = id.coord() / kPageBricks;
    const PageTableLevel& L = level[id.level()];
    return L.directory_offset + (std::uint32_t(p.z) * std::uint32_t(L.pages.y) + std::uint32_t(p.y)) *
                                    std::uint32_t(L.pages.x) + std::uint32_t(p.x);
  }
  SL_HOST_DEVICE static std::uint64_t pool_index(std::uint32_t page, BrickId id) {
    const ivec3 c = id.coord();
    const ivec3 e = c - (c / kPageBricks) * kPageBricks;
    const std::uint32_t in_page = (std::uint32_t(e.z) * kPageBricks + std::uint32_t(e.y)) * kPageBricks + std::uint32_t(e.x);
    return std::uint64_t(page) * kPageEntries + in_page;
  }
};

// Host-side owner. Not thread-safe: the host updates it between frames, the caster only reads views.
class PageTable {
 public:
  PageTable() = default;
  explicit PageTable(const BrickLayout& layout);

  PageEntry get(BrickId id) const { return view().lookup(id); }
  // Sets an entry, allocating its page on first use. SL_CHECKs that the brick is in the layout.
  void set(BrickId id, PageEntry e);
  // Back to Unmapped; a page whose entries are all Unmapped again is returned to the pool.
  void clear(BrickId id) { set(id, PageEntry::unmapped()); }
  // Everything Unmapped, all pages released (keeps the directory).
  void reset();

  std::size_t touched_pages() const { return live_pages_; }
  std::size_t mapped_entries() const { return mapped_entries_; }
  // Directory + allocated pool pages + per-page bookkeeping, in bytes and KiB.
  std::size_t memory_bytes() const;
  double memory_kb() const { return double(memory_bytes()) / 1024.0; }

  PageTableView view() const;

 private:
  BrickLayout layout_{};
  PageTableLevel levels_[kMaxBrickLevels]{};
  std::vector<std::uint32_t> directory_;
  std::vector<std::uint32_t> pool_;        // kPageEntries per page
  std::vector<std::uint16_t> page_used_;   // non-Unmapped entries per page (0 .. 4096)
  std::vector<std::uint32_t> free_pages_;  // released pages, reused before the pool grows
  std::size_t live_pages_ = 0;
  std::size_t mapped_entries_ = 0;
};

}  // namespace sl
