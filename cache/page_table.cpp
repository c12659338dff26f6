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

void PageTableUpdate::clear() {
  dir_index.clear();
  dir_value.clear();
  pool_index.clear();
  pool_value.clear();
}

std::uint64_t PageTableUpdate::pool_words_needed() const {
  std::uint64_t n = 0;
  auto chunk = [&n](std::uint32_t ptr) { n = std::max(n, std::uint64_t(ptr) * kChunkWords); };  // ptr = chunk + 1
  for (std::uint64_t i : pool_index) n = std::max(n, i + 1);
  for (std::uint32_t d : dir_value) chunk(d);
  for (std::uint32_t v : pool_value) {
    if (v != 0 && PageEntry{v}.state() == PageEntry::State::Unmapped) chunk(v);  // a node word
  }
  return n;
}

PageTable::PageTable(const BrickLayout& layout) : layout_(layout) {
  std::uint64_t offset = 0;
  for (int l = 0; l < layout.levels; ++l) {
    levels_[l].pages = (layout.bricks(l) + kDirBricks - 1) / kDirBricks;
    levels_[l].directory_offset = std::uint32_t(offset);
    const ivec3 p = levels_[l].pages;
    offset += std::uint64_t(p.x) * std::uint64_t(p.y) * std::uint64_t(p.z);
  }
  // 2^20 bricks per axis => at most 2^16 directory words per axis; check the total anyway.
  SL_CHECK(offset < (std::uint64_t(1) << 32));
  directory_.assign(std::size_t(offset), 0u);
}

std::uint32_t PageTable::alloc_chunk() {
  std::uint32_t c;
  if (!free_chunks_.empty()) {
    c = *free_chunks_.begin();
    free_chunks_.erase(free_chunks_.begin());
  } else {
    c = std::uint32_t(chunk_used_.size());
    SL_CHECK(c < PageEntry::kPayloadMask);  // a pointer word must read Unmapped as an entry
    pool_.resize(pool_.size() + kChunkWords, 0u);
    chunk_used_.push_back(0);
  }
  ++live_chunks_;
  return c;
}

void PageTable::free_chunk(std::uint32_t c) {
  // Its words are all zero again (that is why it is freed), so a reused or regrown chunk starts
  // empty on the host and in any mirror that received every write.
  --live_chunks_;
  free_chunks_.insert(c);
  // Trim free chunks off the pool's end; give the storage back once it is mostly unused.
  std::size_t n = chunk_used_.size();
  while (n > 0 && !free_chunks_.empty() && *free_chunks_.rbegin() == n - 1) {
    free_chunks_.erase(std::prev(free_chunks_.end()));
    --n;
  }
  if (n == chunk_used_.size()) return;
  pool_.resize(n * kChunkWords);
  chunk_used_.resize(n);
  if (pool_.capacity() > 2 * pool_.size() + 64 * kChunkWords) {
    pool_.shrink_to_fit();
    chunk_used_.shrink_to_fit();
  }
}

void PageTable::set(BrickId id, PageEntry e, PageTableUpdate* changed) {
  SL_CHECK(layout_.contains(id));
  const PageTableView v = view();
  const std::uint32_t di = v.directory_index(id);
  const bool mapped = e.state() != PageEntry::State::Unmapped;
  std::uint32_t node = directory_[di];
  std::uint64_t nw = node ? PageTableView::node_word(node - 1, id) : 0;
  std::uint32_t leaf = node ? pool_[nw] : 0;
  if (leaf == 0 && !mapped) return;  // clearing an entry of a region never touched: nothing to do
  if (node == 0) {
    node = alloc_chunk() + 1;
    directory_[di] = node;
    if (changed) changed->dir_index.push_back(di);
    nw = PageTableView::node_word(node - 1, id);
  }
  if (leaf == 0) {
    leaf = alloc_chunk() + 1;  // (pool_ may have moved: index, never hold references)
    pool_[nw] = leaf;
    ++chunk_used_[node - 1];
    if (changed) changed->pool_index.push_back(nw);
  }
  const std::uint64_t ew = PageTableView::entry_word(leaf - 1, id);
  const bool was_mapped = pool_[ew] != 0;
  pool_[ew] = e.bits;
  if (changed) changed->pool_index.push_back(ew);
  if (was_mapped == mapped) return;
  if (mapped) {
    ++chunk_used_[leaf - 1];
    ++mapped_entries_;
    return;
  }
  --mapped_entries_;
  if (--chunk_used_[leaf - 1] > 0) return;
  // The leaf chunk holds nothing: unlink and free it, and its node chunk if that empties too.
  pool_[nw] = 0;
  if (changed) changed->pool_index.push_back(nw);
  free_chunk(leaf - 1);
  if (--chunk_used_[node - 1] > 0) return;
  directory_[di] = 0;
  if (changed) changed->dir_index.push_back(di);
  free_chunk(node - 1);
}

void PageTable::reset() {
  std::fill(directory_.begin(), directory_.end(), 0u);
  pool_.clear();
  pool_.shrink_to_fit();
  chunk_used_.clear();
  chunk_used_.shrink_to_fit();
  free_chunks_.clear();
  live_chunks_ = 0;
  mapped_entries_ = 0;
}

std::size_t PageTable::memory_bytes() const {
  // What is actually held: capacities, free chunks still in the pool, and the free set's nodes
  // (about four words each in a red-black tree).
  return directory_.capacity() * sizeof(std::uint32_t) + pool_.capacity() * sizeof(std::uint32_t) +
         chunk_used_.capacity() * sizeof(std::uint8_t) + free_chunks_.size() * 4 * sizeof(void*);
}

std::uint32_t PageTable::pool_word(std::uint64_t i) const { return i < pool_.size() ? pool_[std::size_t(i)] : 0u; }

PageTableView PageTable::view() const {
  PageTableView v;
  v.directory = directory_.data();
  v.pool = pool_.data();
  v.levels = layout_.levels;
  for (int l = 0; l < kMaxBrickLevels; ++l) v.level[l] = levels_[l];
  return v;
}

}  // namespace sl
