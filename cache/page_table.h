// Per-level multi-level page table (DESIGN.md "Virtual memory", after Hadwiger et al. 2012, the paper's [14]).
// A small directory per level (one 32-bit word per 16³ bricks) points into one pool of 64-word
// chunks allocated only where an entry is set, so a level of 30 million bricks costs memory only
// where rays went, in proportion to the bricks touched. Pointer-free inside: pointer words are
// chunk indices + 1 (0 = none), chunks live in one pool array.
#pragma once

#include <cstdint>
#include <cstring>
#include <set>
#include <vector>

#include "cache/brick.h"
#include "core/util/config.h"

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

// Geometry of the tree below each level's directory (DESIGN.md "Virtual memory": memory proportional to
// the bricks touched). A directory word covers 16³ bricks and points to a *node chunk* of 4³ words,
// each of which points to a *leaf chunk* of 4³ entries (4³ bricks). Node and leaf chunks are the same
// 64 words and live in one pool, allocated on first touch and freed when they hold nothing: a brick
// alone in its region costs two chunks (512 bytes), not a 16³-brick page (16 KB).
inline constexpr int kDirBricks = 16;   // bricks per directory word, per axis
inline constexpr int kChunkBricks = 4;  // bricks per leaf chunk, per axis (and leaf chunks per node chunk)
inline constexpr int kChunkWords = kChunkBricks * kChunkBricks * kChunkBricks;
static_assert(kChunkBricks * kChunkBricks == kDirBricks, "a node chunk covers exactly one directory word");

struct PageTableLevel {
  ivec3 pages{0};                  // directory grid dims: ceil(bricks / 16)
  std::uint32_t directory_offset = 0;  // first directory entry of this level
};
static_assert(sizeof(PageTableLevel) == 16);

// What the caster reads: plain, two base pointers plus per-level geometry. Valid until the next
// PageTable::set that allocates a chunk (the pool may move) — build it once per frame.
// Directory words and node-chunk words hold a chunk index + 1 (0: none). A pointer word is never a
// valid non-zero entry: pointers stay below 2^30, so their state bits read Unmapped, and an Unmapped
// entry is always all zero (PageTableUpdate::pool_words_needed relies on this).
struct PageTableView {
  const std::uint32_t* directory = nullptr;  // per level: node chunk index + 1, or 0
  const std::uint32_t* pool = nullptr;       // chunks of kChunkWords words each
  PageTableLevel level[kMaxBrickLevels];
  std::int32_t levels = 0;

  // Entry of brick `id`; a brick outside the level or in a region never touched reads Unmapped.
  SL_HOST_DEVICE PageEntry lookup(BrickId id) const {
    const int l = id.level();
    if (l >= levels) return PageEntry::unmapped();
    const ivec3 p = id.coord() / kDirBricks;
    const PageTableLevel& L = level[l];
    if (p.x >= L.pages.x || p.y >= L.pages.y || p.z >= L.pages.z) return PageEntry::unmapped();
    const std::uint32_t node = directory[directory_index(id)];
    if (node == 0) return PageEntry::unmapped();
    const std::uint32_t leaf = pool[node_word(node - 1, id)];
    if (leaf == 0) return PageEntry::unmapped();
    return PageEntry{pool[entry_word(leaf - 1, id)]};
  }

  // Word indices along a brick's path (a device mirror copies words by index).
  SL_HOST_DEVICE std::uint32_t directory_index(BrickId id) const {
    const ivec3 p = id.coord() / kDirBricks;
    const PageTableLevel& L = level[id.level()];
    return L.directory_offset + (std::uint32_t(p.z) * std::uint32_t(L.pages.y) + std::uint32_t(p.y)) *
                                    std::uint32_t(L.pages.x) + std::uint32_t(p.x);
  }
  // Word of node chunk `chunk` that points to the leaf chunk holding `id`.
  SL_HOST_DEVICE static std::uint64_t node_word(std::uint32_t chunk, BrickId id) {
    return chunk_word(chunk, id.coord() / kChunkBricks);
  }
  // Word of leaf chunk `chunk` that holds the entry of `id`.
  SL_HOST_DEVICE static std::uint64_t entry_word(std::uint32_t chunk, BrickId id) {
    return chunk_word(chunk, id.coord());
  }
  SL_HOST_DEVICE static std::uint64_t chunk_word(std::uint32_t chunk, ivec3 c) {
    const ivec3 e = c - (c / kChunkBricks) * kChunkBricks;
    const std::uint32_t in_chunk =
        (std::uint32_t(e.z) * kChunkBricks + std::uint32_t(e.y)) * kChunkBricks + std::uint32_t(e.x);
    return std::uint64_t(chunk) * kChunkWords + in_chunk;
  }
};

// Page-table words changed on the host, with their current values. Directory word i and pool word j
// are the words of PageTableView::directory / pool, so a device mirrors the host layout 1:1.
struct PageTableUpdate {
  std::vector<std::uint32_t> dir_index, dir_value;
  std::vector<std::uint64_t> pool_index;
  std::vector<std::uint32_t> pool_value;
  std::size_t words() const { return dir_index.size() + pool_index.size(); }
  bool empty() const { return words() == 0; }
  void clear();
  // Pool words a mirror must hold to apply this update: the largest word index + 1 written, and the
  // chunks the pointer words written (directory values, non-zero pool words in the Unmapped state)
  // name — a pointer may arrive before the words of its chunk (split_page_table_update).
  std::uint64_t pool_words_needed() const;
};

// Host-side owner. Not thread-safe: the host updates it between frames, the caster only reads views.
class PageTable {
 public:
  PageTable() = default;
  explicit PageTable(const BrickLayout& layout);

  PageEntry get(BrickId id) const { return view().lookup(id); }
  // Sets an entry, allocating its chunks on first use; a chunk left holding nothing is freed. The
  // indices of the words written (directory, pool) are appended to `changed` when given (values
  // are left for the caller to read at sync time). SL_CHECKs that the brick is in the layout.
  void set(BrickId id, PageEntry e, PageTableUpdate* changed = nullptr);
  // Back to Unmapped.
  void clear(BrickId id) { set(id, PageEntry::unmapped()); }
  // Everything Unmapped, all chunks released (keeps the directory).
  void reset();

  std::size_t live_chunks() const { return live_chunks_; }
  std::size_t mapped_entries() const { return mapped_entries_; }
  // What the table holds, in bytes: directory, pool (with free chunks not yet trimmed) and per-chunk
  // bookkeeping. Freed chunks at the pool's end are trimmed, and the pool's storage shrinks when it
  // is mostly unused, so the figure falls again when bricks are unmapped.
  std::size_t memory_bytes() const;

  PageTableView view() const;
  std::uint32_t directory_word(std::uint32_t i) const { return directory_[i]; }
  // Pool word i, or 0 past the pool's end (a word written just before its chunk was trimmed).
  std::uint32_t pool_word(std::uint64_t i) const;

 private:
  std::uint32_t alloc_chunk();
  void free_chunk(std::uint32_t chunk);

  BrickLayout layout_{};
  PageTableLevel levels_[kMaxBrickLevels]{};
  std::vector<std::uint32_t> directory_;
  std::vector<std::uint32_t> pool_;        // kChunkWords per chunk
  std::vector<std::uint8_t> chunk_used_;   // non-zero words per chunk (0 .. 64)
  std::set<std::uint32_t> free_chunks_;    // lowest first, so the pool's tail empties and is trimmed
  std::size_t live_chunks_ = 0;
  std::size_t mapped_entries_ = 0;
};

}  // namespace sl
