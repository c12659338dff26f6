#include "cache/brick_cache.h"

#include <algorithm>
#include <atomic>

#include "cache/page_table.h"
#include "core/util/error.h"

namespace sl {
namespace {

std::size_t round_up(std::size_t n, std::size_t a) { return (n + a - 1) / a * a; }

}  // namespace

BrickCache::BrickCache(const BrickLayout& layout, VoxelType voxel_type, std::optional<VoxelType> label_type,
                       std::size_t budget_mb)
    : layout_(layout), voxel_type_(voxel_type), label_type_(label_type.value_or(VoxelType::U32)) {
  const std::size_t n = layout.stored_voxels();
  voxel_stride_ = round_up(n * std::size_t(voxel_size(voxel_type)), 64);
  label_stride_ = label_type ? round_up(n * std::size_t(voxel_size(*label_type)), 64) : 0;
  // The voxel mask: u8/u16 volumes (core/occupancy/fine_occupancy.h), a bit per stored voxel's cell.
  if (voxel_type == VoxelType::U8 || voxel_type == VoxelType::U16) {
    const std::size_t s = std::size_t(layout.stored_size());
    mask_words_ = round_up((s * s * s + 63) / 64, 8);  // whole 64-byte lines per slot
  }
  const std::size_t per_slot = voxel_stride_ + label_stride_ + mask_words_ * sizeof(std::uint64_t);
  const std::uint64_t budget = std::uint64_t(budget_mb) << 20;
  // Slots are addressed by 30-bit page-table payloads.
  const std::uint64_t slots = std::min<std::uint64_t>(budget / per_slot, std::uint64_t(PageEntry::kPayloadMask) + 1);
  if (slots < std::uint64_t(layout.levels)) {
    const std::uint64_t need = (std::uint64_t(per_slot) * std::uint64_t(layout.levels) + (1u << 20) - 1) >> 20;
    throw InputError("--cache-mb", "a budget of " + std::to_string(budget_mb) + " MB holds " +
                                       std::to_string(slots) + " bricks of " +
                                       std::to_string(per_slot / 1024) + " KB, but the volume has " +
                                       std::to_string(layout.levels) +
                                       " levels and needs at least one brick per level (use at least " +
                                       std::to_string(need) + " MB)");
  }
  slot_count_ = std::uint32_t(slots);
  // for_overwrite: no zeroing pass, so untouched slots never become resident memory.
  voxels_ = std::make_unique_for_overwrite<std::byte[]>(std::size_t(slots) * voxel_stride_);
  if (label_stride_) labels_ = std::make_unique_for_overwrite<std::byte[]>(std::size_t(slots) * label_stride_);
  if (mask_words_) masks_ = std::make_unique_for_overwrite<std::uint64_t[]>(std::size_t(slots) * mask_words_);
  mask_key_.assign(slot_count_, kNoMask);
  if (mask_words_) cells_.assign(std::size_t(slot_count_) * BrickCacheView::kCellWords, 0u);
  usage_.assign(slot_count_, 0u);
  owner_.assign(slot_count_, BrickId::invalid());
  free_.resize(slot_count_);
  for (std::uint32_t i = 0; i < slot_count_; ++i) free_[i] = slot_count_ - 1 - i;
}

std::uint32_t BrickCache::last_used(std::uint32_t slot) const {
  // Casters may be writing stamps concurrently (atomic_ref needs a non-const object).
  return std::atomic_ref<std::uint32_t>(const_cast<std::uint32_t&>(usage_[slot])).load(std::memory_order_relaxed);
}

std::optional<BrickCache::Allocation> BrickCache::allocate(BrickId id, std::uint32_t frame) {
  SL_CHECK(layout_.contains(id));
  Allocation a;
  if (!free_.empty()) {
    a.slot = free_.back();
    free_.pop_back();
  } else {
    bool found = false;
    for (int pass = 0; pass < 2 && !found; ++pass) {
      if (pass == 1 || candidates_frame_ != frame) {
        // (Re)build: every slot last used before `frame`, oldest (then lowest slot) at the back.
        candidates_.clear();
        for (std::uint32_t s = 0; s < slot_count_; ++s) {
          const std::uint32_t u = last_used(s);
          if (u < frame && owner_[s].valid()) candidates_.emplace_back(u, s);
        }
        std::sort(candidates_.begin(), candidates_.end(), [](const auto& x, const auto& y) {
          return x.first != y.first ? x.first > y.first : x.second > y.second;
        });
        candidates_frame_ = frame;
      }
      while (!candidates_.empty()) {
        const auto [stamp, s] = candidates_.back();
        candidates_.pop_back();
        // Skip entries gone stale since the sort: the slot was used again, or freed and reused.
        if (last_used(s) != stamp || !owner_[s].valid()) continue;
        a.slot = s;
        found = true;
        break;
      }
    }
    if (!found) return std::nullopt;
    a.evicted = owner_[a.slot];
    ++evictions_;
  }
  owner_[a.slot] = id;
  mask_key_[a.slot] = kNoMask;
  std::atomic_ref<std::uint32_t>(usage_[a.slot]).store(frame, std::memory_order_relaxed);
  return a;
}

void BrickCache::release(std::uint32_t slot) {
  SL_CHECK(slot < slot_count_ && owner_[slot].valid());
  owner_[slot] = BrickId::invalid();
  mask_key_[slot] = kNoMask;
  std::atomic_ref<std::uint32_t>(usage_[slot]).store(0u, std::memory_order_relaxed);
  free_.push_back(slot);
}

std::span<std::byte> BrickCache::slot_voxels(std::uint32_t slot) {
  SL_CHECK(slot < slot_count_);
  return {voxels_.get() + std::size_t(slot) * voxel_stride_,
          std::size_t(layout_.stored_voxels()) * std::size_t(voxel_size(voxel_type_))};
}

std::span<std::byte> BrickCache::slot_labels(std::uint32_t slot) {
  SL_CHECK(slot < slot_count_);
  if (!label_stride_) return {};
  return {labels_.get() + std::size_t(slot) * label_stride_,
          std::size_t(layout_.stored_voxels()) * std::size_t(voxel_size(label_type_))};
}

std::span<std::uint64_t> BrickCache::slot_mask(std::uint32_t slot) {
  SL_CHECK(slot < slot_count_);
  if (!mask_words_) return {};
  return {masks_.get() + std::size_t(slot) * mask_words_, mask_words_};
}

std::span<const std::uint64_t> BrickCache::slot_mask(std::uint32_t slot) const {
  SL_CHECK(slot < slot_count_);
  if (!mask_words_) return {};
  return {masks_.get() + std::size_t(slot) * mask_words_, mask_words_};
}

BrickCacheView BrickCache::view() {
  BrickCacheView v;
  v.voxels = voxels_.get();
  v.labels = labels_.get();
  v.usage = usage_.data();
  v.voxel_stride = voxel_stride_;
  v.label_stride = label_stride_;
  v.slot_count = slot_count_;
  v.stored = layout_.stored_size();
  v.voxel_type = voxel_type_;
  v.label_type = label_type_;
  v.has_labels = label_stride_ ? 1 : 0;
  v.masks = masks_.get();
  v.mask_words = std::uint32_t(mask_words_);
  v.cells = mask_words_ ? cells_.data() : nullptr;
  return v;
}

}  // namespace sl
