#include "cache/out_of_core/simulated_cast_device.h"

#include <algorithm>
#include <cstring>

#include "core/util/config.h"

namespace sl {

void SimulatedCastDevice::configure(const DeviceConfig& c) {
  config_ = c;
  const std::uint64_t n = c.layout.stored_voxels();
  voxel_stride_ = n * std::uint64_t(voxel_size(c.voxel_type));
  label_stride_ = c.has_labels ? n * std::uint64_t(voxel_size(c.label_type)) : 0;
  voxels_.assign(std::size_t(voxel_stride_ * c.slot_count), std::byte{0});
  labels_.assign(std::size_t(label_stride_ * c.slot_count), std::byte{0});
  usage_.assign(c.slot_count, 0u);
  directory_.assign(c.directory_words, 0u);
  pool_.clear();
  misses_ = std::make_unique<MissBuffer>(c.miss_capacity);
  uploads_in_flight_.clear();
  slot_in_flight_.assign(c.slot_count, false);
  held_words_.clear();
}

void SimulatedCastDevice::write_page_words(const PageTableUpdate& u) {
  const std::uint64_t need = u.pool_words_needed();
  if (need > pool_.size()) pool_.resize(std::size_t((need + kChunkWords - 1) / kChunkWords * kChunkWords), 0u);
  for (std::size_t k = 0; k < u.dir_index.size(); ++k) directory_[u.dir_index[k]] = u.dir_value[k];
  for (std::size_t k = 0; k < u.pool_index.size(); ++k) pool_[std::size_t(u.pool_index[k])] = u.pool_value[k];
}

void SimulatedCastDevice::begin_frame() {
  // The stream of last frame's uploads has completed: the slots hold their bricks, and the words
  // mapping them become visible.
  for (UploadInFlight& p : uploads_in_flight_) {
    std::memcpy(voxels_.data() + p.slot * voxel_stride_, p.voxels.data(), p.voxels.size());
    if (label_stride_ && !p.labels.empty()) {
      std::memcpy(labels_.data() + p.slot * label_stride_, p.labels.data(), p.labels.size());
    }
    slot_in_flight_[p.slot] = false;
  }
  uploads_in_flight_.clear();
  write_page_words(held_words_);
  held_words_.clear();
  this_frame_ = SimulatedTransfers{};
  ++this_frame_.frames;
  ++total_.frames;
}

void SimulatedCastDevice::upload_bricks(std::span<const BrickUpload> bricks) {
  for (const BrickUpload& b : bricks) {
    SL_CHECK(b.slot < config_.slot_count && b.voxels.size() == voxel_stride_);
    UploadInFlight p{b.slot, {b.voxels.begin(), b.voxels.end()}, {}};  // staged: the host may reuse its buffer
    if (label_stride_) {
      SL_CHECK(b.labels.size() == label_stride_);
      p.labels.assign(b.labels.begin(), b.labels.end());
    }
    slot_in_flight_[b.slot] = true;
    uploads_in_flight_.push_back(std::move(p));
    const std::uint64_t bytes = b.voxels.size() + b.labels.size();
    ++this_frame_.bricks_uploaded;
    ++total_.bricks_uploaded;
    this_frame_.brick_bytes += bytes;
    total_.brick_bytes += bytes;
  }
}

void SimulatedCastDevice::sync_page_table(const PageTableUpdate& update) {
  PageTableUpdate now;
  split_page_table_update(update, slot_in_flight_, now, held_words_);
  write_page_words(now);
  const std::uint64_t deferred = update.words() - now.words();
  this_frame_.page_words += update.words();
  total_.page_words += update.words();
  this_frame_.page_words_deferred += deferred;
  total_.page_words_deferred += deferred;
}

VirtualMemoryView SimulatedCastDevice::device_view() {
  VirtualMemoryView vm;
  vm.layout = &config_.layout;
  vm.page_table = config_.page_table_geometry;
  vm.page_table.directory = directory_.data();
  vm.page_table.pool = pool_.data();
  vm.cache = device_cache_view(config_, voxels_.data(), labels_.data(), usage_.data(), voxel_stride_, label_stride_);
  vm.misses = misses_->view();
  vm.has_labels = config_.has_labels;
  return vm;
}

void SimulatedCastDevice::cast(const CastRequest& r, Frame& frame, CastFeedback& fb) {
  misses_->clear();
  // The segment lists cross to the device as a copy, as the CUDA device uploads them.
  SegmentListBuffer lists;
  SkipInputs skip = r.skip;
  if (skip.method == SkipMethod::SparseLeap || skip.method == SkipMethod::BBox) {
    lists.assign(r.skip.lists);
    skip.lists = lists.view();
  }
  VirtualMemoryView vm = device_view();
  // Its own counters, added to the host's after the cast, as the CUDA device does.
  shortfall_.assign(SampleShortfall::kWords, 0);
  vm.shortfall = r.host.shortfall;
  vm.shortfall.counters = r.host.shortfall.counters ? shortfall_.data() : nullptr;
  cast_virtual_frame(r.params, r.gen, r.vbox, skip, r.frame, vm, frame);
  add_shortfall(r.host.shortfall, shortfall_);
  // Copied back once per frame: the distinct misses and the slots used in this frame.
  fb.misses = misses_->drain();
  fb.used_slots.clear();
  for (std::uint32_t s = 0; s < config_.slot_count; ++s) {
    if (usage_[s] == r.frame) fb.used_slots.push_back(s);
  }
  this_frame_.misses_returned += fb.misses.size();
  total_.misses_returned += fb.misses.size();
  this_frame_.usage_returned += fb.used_slots.size();
  total_.usage_returned += fb.used_slots.size();
}

PageEntry SimulatedCastDevice::entry(BrickId id) const {
  PageTableView v = config_.page_table_geometry;
  v.directory = directory_.data();
  v.pool = pool_.data();
  return v.lookup(id);
}

std::span<const std::byte> SimulatedCastDevice::slot_voxels(std::uint32_t slot) const {
  SL_CHECK(slot < config_.slot_count);
  return {voxels_.data() + slot * voxel_stride_, std::size_t(voxel_stride_)};
}

}  // namespace sl
