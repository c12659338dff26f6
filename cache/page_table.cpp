#include "cache/page_table.h"

#include <algorithm>
#include <cmath>
#include <cstring>

namespace sl {

bool constant_encodable(float value, VoxelType t) {
  if (t == VoxelType::F32) {
    std::uint32_t f;
    std::memcpy(&f, &value, sizeof(f));
    return (f & 3u) == 0;
  }
  return value >= 0.0f && value <= float(PageEntry::kPayloadMask) && std::floor(value) == value;
}

PageEntry constant_entry(float value, VoxelType t) {
  SL_CHECK(constant_encodable(value, t));
  if (t == VoxelType::F32) {
    std::uint32_t f;
    std::memcpy(&f, &value, sizeof(f));
    return PageEntry::constant_bits(f >> 2);
  }
  return PageEntry::constant_bits(std::uint32_t(value));
}

PageTable::PageTable(const BrickLayout& layout) : layout_(layout) {
  std::uint64_t offset = 0;
  for (int l = 0; l < layout.levels; ++l) {
    levels_[l].pages = (layout.bricks(l) + kPageBricks - 1) / kPageBricks;
    levels_[l].directory_offset = std::uint32_t(offset);
    const ivec3 p = levels_[l].pages;
    offset += std::uint64_t(p.x) * std::uint64_t(p.y) * std::uint64_t(p.z);
  }
  // 2^20 bricks per axis => at most 2^16 pages per axis; the directory of a whole pyramid stays far
  // below 2^32 entries for any volume BrickLayout accepts of sensible size, but check anyway.
  SL_CHECK(offset < (std::uint64_t(1) << 32));
  directory_.assign(std::size_t(offset), 0u);
}

void PageTable::set(BrickId id, PageEntry e) {
  SL_CHECK(layout_.contains(id));
  const int l = id.level();
  const ivec3 c = id.coord();
  const ivec3 p = c / kPageBricks;
  const PageTableLevel& L = levels_[l];
  std::uint32_t& dir = directory_[L.directory_offset +
                                  (std::uint32_t(p.z) * std::uint32_t(L.pages.y) + std::uint32_t(p.y)) *
                                      std::uint32_t(L.pages.x) + std::uint32_t(p.x)];
  const bool mapped = e.state() != PageEntry::State::Unmapped;
  if (dir == 0) {
    if (!mapped) return;  // clearing an entry of a page that does not exist: nothing to do
    std::uint32_t page;
    if (!free_pages_.empty()) {
      page = free_pages_.back();
      free_pages_.pop_back();
    } else {
      page = std::uint32_t(page_used_.size());
      pool_.resize(pool_.size() + kPageEntries, 0u);
      page_used_.push_back(0);
    }
    dir = page + 1;
    ++live_pages_;
  }
  const std::uint32_t page = dir - 1;
  const ivec3 q = c - p * kPageBricks;
  std::uint32_t& entry =
      pool_[std::size_t(page) * kPageEntries +
            (std::size_t(q.z) * kPageBricks + std::size_t(q.y)) * kPageBricks + std::size_t(q.x)];
  const bool was_mapped = PageEntry{entry}.state() != PageEntry::State::Unmapped;
  entry = e.bits;
  if (was_mapped != mapped) {
    if (mapped) {
      ++page_used_[page];
      ++mapped_entries_;
    } else {
      --page_used_[page];
      --mapped_entries_;
    }
  }
  if (page_used_[page] == 0) {  // page all Unmapped again (its entries are all zero): release it
    dir = 0;
    free_pages_.push_back(page);
    --live_pages_;
  }
}

void PageTable::reset() {
  std::fill(directory_.begin(), directory_.end(), 0u);
  std::fill(pool_.begin(), pool_.end(), 0u);
  std::fill(page_used_.begin(), page_used_.end(), std::uint16_t(0));
  free_pages_.clear();
  for (std::uint32_t p = std::uint32_t(page_used_.size()); p-- > 0;) free_pages_.push_back(p);
  live_pages_ = 0;
  mapped_entries_ = 0;
}

std::size_t PageTable::memory_bytes() const {
  // What is actually held: capacities, and pages on the free list still occupy the pool.
  return directory_.capacity() * sizeof(std::uint32_t) + pool_.capacity() * sizeof(std::uint32_t) +
         page_used_.capacity() * sizeof(std::uint16_t) + free_pages_.capacity() * sizeof(std::uint32_t);
}

PageTableView PageTable::view() const {
  PageTableView v;
  v.directory = directory_.data();
  v.pool = pool_.data();
  v.levels = layout_.levels;
  for (int l = 0; l < kMaxBrickLevels; ++l) v.level[l] = levels_[l];
  return v;
}

}  // namespace sl
