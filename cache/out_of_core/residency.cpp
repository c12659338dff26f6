#include "cache/out_of_core/residency.h"

#include <algorithm>
#include <cstdio>
#include <cstring>

#include "core/occupancy/fine_occupancy.h"
#include "core/util/parallel.h"
#include "core/util/printable.h"

namespace sl {

namespace {

// BrickCacheView::cells from a slot's mask. Fine cell c (per axis, payload voxels [cC, (c+1)C)) holds
// the samples whose trilinear cell is anchored at payload voxels cC - 1 .. (c+1)C - 1 — within half a
// voxel of the cell, rounding included — which are stored anchors cC .. (c+1)C. So a set mask bit at
// stored anchor s marks cell s / C and, when s is a multiple of C, cell s / C - 1.
void fine_cells_of_mask(const std::uint64_t* mask, int row_words, int brick, std::span<std::uint64_t> cells) {
  constexpr int n = BrickCacheView::kCellsPerAxis;
  const int c = brick / n;
  const auto cells_of = [&](int s, int out[2]) {
    int k = 0;
    if (s / c < n) out[k++] = s / c;
    if (s % c == 0 && s > 0) out[k++] = s / c - 1;
    return k;
  };
  std::fill(cells.begin(), cells.end(), 0u);
  const int stored = brick + 2;
  for (int z = 0; z <= brick; ++z) {  // stored anchors 0 .. B are the payload's cells
    int cz[2];
    const int nz = cells_of(z, cz);
    for (int y = 0; y <= brick; ++y) {
      int cy[2];
      const int ny = cells_of(y, cy);
      const std::uint64_t* row = mask + (std::size_t(z) * std::size_t(stored) + std::size_t(y)) * std::size_t(row_words);
      for (int x = 0; x <= brick; ++x) {
        if (((row[x >> 6] >> (x & 63)) & 1u) == 0u) continue;
        int cx[2];
        const int nx = cells_of(x, cx);
        for (int i = 0; i < nz; ++i) {
          for (int j = 0; j < ny; ++j) {
            for (int k = 0; k < nx; ++k) {
              const int bit = (cz[i] * n + cy[j]) * n + cx[k];
              cells[std::size_t(bit >> 6)] |= std::uint64_t(1) << (bit & 63);
            }
          }
        }
      }
    }
  }
}

// Sorts and de-duplicates the changed words' indices and reads each word's current value.
template <class Index, class Read>
void gather_words(std::vector<Index>& index, std::vector<std::uint32_t>& value, Read&& read) {
  std::sort(index.begin(), index.end());
  index.erase(std::unique(index.begin(), index.end()), index.end());
  value.resize(index.size());
  for (std::size_t k = 0; k < index.size(); ++k) value[k] = read(index[k]);
}

}  // namespace

Residency::Residency(std::shared_ptr<const VolumeSource> source, const BrickLayout& layout,
                     const OutOfCoreSettings& settings, int block, std::unique_ptr<CastDevice> device)
    : source_(std::move(source)),
      layout_(layout),
      page_table_(layout_),
      cache_(layout_, source_->desc().type,
             source_->has_labels() ? std::optional<VoxelType>(source_->label_type()) : std::nullopt,
             settings.cache_mb),
      misses_(1u << 16),
      loader_(source_, layout_, settings.loader_threads, settings.retry, BrickLoader::kDefaultFinishedBytes, block),
      device_(device ? std::move(device) : std::make_unique<CpuCastDevice>()),
      device_memory_(!device_->shares_host_memory()) {}

void Residency::configure_device() {
  DeviceConfig dc;
  dc.layout = layout_;
  dc.voxel_type = source_->desc().type;
  dc.has_labels = source_->has_labels();
  dc.label_type = source_->has_labels() ? source_->label_type() : VoxelType::U32;
  dc.slot_count = cache_.slot_count();
  dc.miss_capacity = misses_.capacity();
  dc.page_table_geometry = page_table_.view();
  dc.page_table_geometry.directory = nullptr;
  dc.page_table_geometry.pool = nullptr;
  for (int l = 0; l < layout_.levels; ++l) {
    const PageTableLevel& L = dc.page_table_geometry.level[l];
    dc.directory_words = std::max<std::size_t>(
        dc.directory_words, std::size_t(L.directory_offset) + std::size_t(L.pages.x) * L.pages.y * L.pages.z);
  }
  device_->configure(dc);
}

void Residency::set_page_entry(BrickId id, PageEntry e) {
  // With device memory the table logs the words it writes (entry, chunk pointers, directory), so the
  // device mirror receives only those.
  page_table_.set(id, e, device_memory_ ? &changed_words_ : nullptr);
}

void Residency::map_culled_empty(BrickId id) {
  set_page_entry(id, PageEntry::empty());
  culled_empty_pages_.push_back(id);
}

void Residency::forget_culled_empty_pages() {
  for (const BrickId id : culled_empty_pages_) {
    if (page_table_.get(id).state() == PageEntry::State::Empty) set_page_entry(id, PageEntry::unmapped());
  }
  culled_empty_pages_.clear();
}

void Residency::begin_frame() {
  loads_this_frame_ = 0;
  if (device_memory_) device_->begin_frame();  // last frame's uploads have landed
}

void Residency::report_failure(const BrickFailure& f) {
  if (reported_causes_.insert(f.cause).second) {
    std::fprintf(stderr, "sparseleap: warning: brick failed to load, rendered as missing: %s\n",
                 printable(f.reason).c_str());
  }
}

Residency::Placement Residency::place(LoadedBrick&& b, std::uint32_t frame, bool prefetched) {
  Placement p;
  // Protects the bricks the last frame used: the view's working set is not evicted to make room for
  // another brick of the same view (that would thrash the cache and stall the view).
  const auto a = page_table_.get(b.id).is_resident() ? std::nullopt : cache_.allocate(b.id, frame - 1);
  if (!a) {  // resident already, or no room: requested again when there is (free_slots_for_loads)
    loader_.recycle(std::move(b));
    return p;
  }
  p.placed = true;
  p.evicted = a->evicted;
  if (a->evicted.valid()) set_page_entry(a->evicted, PageEntry::unmapped());
  // Stamped older than the last frame: the first room a frame's own load may take.
  if (prefetched) cache_.view().touch(a->slot, frame >= 2 ? frame - 2 : 0);
  const BrickId id = b.id;
  if (device_memory_) {
    stage_upload(std::move(b), a->slot);
  } else {
    copy_to_host_slot(b, a->slot);
  }
  set_page_entry(id, PageEntry::resident(a->slot));
  if (!prefetched) ++loads_this_frame_;
  if (!device_memory_) loader_.recycle(std::move(b));
  return p;
}

void Residency::copy_to_host_slot(const LoadedBrick& b, std::uint32_t slot) {
  auto vox = cache_.slot_voxels(slot);
  std::memcpy(vox.data(), b.intensity.data(), std::min(vox.size(), b.intensity.size()));
  if (cache_.has_labels() && !b.labels.empty()) {
    auto lab = cache_.slot_labels(slot);
    std::memcpy(lab.data(), b.labels.data(), std::min(lab.size(), b.labels.size()));
  }
}

// The device copies the brick (asynchronously); the host slot stays untouched (and, being allocated
// for overwrite, uncommitted): the host only does the bookkeeping.
void Residency::stage_upload(LoadedBrick&& b, std::uint32_t slot) {
  BrickUpload u;
  u.slot = slot;
  u.id = b.id;
  u.voxels = b.intensity;
  if (cache_.has_labels() && !b.labels.empty()) u.labels = b.labels;
  uploads_.push_back(u);
  staged_.push_back(std::move(b));  // (a moved vector keeps its buffer, so the spans stay valid)
}

void Residency::finish_uploads() {
  if (!device_memory_) return;
  device_->upload_bricks(uploads_);
  uploads_.clear();
  for (LoadedBrick& b : staged_) loader_.recycle(std::move(b));
  staged_.clear();
}

std::size_t Residency::free_slots_for_loads() const {
  const std::size_t taken = slots_used_last_ + loads_this_frame_ + loader_.pending();
  return cache_.slot_count() > taken ? cache_.slot_count() - taken : 0;
}

bool Residency::update_masks(const CullParams& cull, std::uint64_t key, bool linear) {
  if (device_memory_ || !cache_.masks_supported() || !linear ||
      (cull.mode != RenderMode::Dvr && cull.mode != RenderMode::Labels)) {
    return false;
  }
  if (key == BrickCache::kNoMask) key = 1;
  std::vector<std::uint32_t> stale;
  for (std::uint32_t s = 0; s < cache_.slot_count(); ++s) {
    if (cache_.brick_in(s).valid() && cache_.mask_key(s) != key) stale.push_back(s);
  }
  if (stale.empty()) return true;
  const VoxelMaskBuilder builder(source_->desc().type, cull);
  const bool labels = cull.enabled != nullptr && cache_.has_labels();
  parallel_for(0, int(stale.size()), [&](int i) { build_mask(stale[std::size_t(i)], builder, labels); });
  for (const std::uint32_t s : stale) cache_.set_mask_key(s, key);
  return true;
}

// A slot's stored voxels as a small dense volume: its cells are the trilinear cells SlotSampler blends.
void Residency::build_mask(std::uint32_t slot, const VoxelMaskBuilder& builder, bool labels) {
  const int n = layout_.stored_size();
  VolumeView vox;
  vox.data = cache_.slot_voxels(slot).data();
  vox.dims = ivec3(n);
  vox.type = source_->desc().type;
  VolumeView lab;
  if (labels) {
    lab.data = cache_.slot_labels(slot).data();
    lab.dims = ivec3(n);
    lab.type = source_->label_type();
  }
  // Built in rows of whole words (the builder's layout), then packed a bit per stored voxel.
  const int row_words = (n + 63) / 64;
  thread_local std::vector<std::uint64_t> rows;
  rows.assign(std::size_t(n) * std::size_t(n) * std::size_t(row_words), 0u);
  builder.build(vox, labels ? &lab : nullptr, row_words, rows.data(), /*parallel=*/false);
  const std::span<std::uint64_t> bits = cache_.slot_mask(slot);
  std::fill(bits.begin(), bits.end(), 0u);
  std::size_t bit = 0;
  for (std::size_t r = 0; r < std::size_t(n) * std::size_t(n); ++r) {
    const std::uint64_t* row = rows.data() + r * std::size_t(row_words);
    for (int x = 0; x < n; ++x, ++bit) {
      if ((row[x >> 6] >> (x & 63)) & 1u) bits[bit >> 6] |= std::uint64_t(1) << (bit & 63u);
    }
  }
  fine_cells_of_mask(rows.data(), row_words, layout_.brick_size, cache_.slot_cells(slot));
}

VirtualMemoryView Residency::host_view(bool masks) {
  BrickCacheView cache = cache_.view();
  if (!masks) {
    cache.masks = nullptr;
    cache.cells = nullptr;
  }
  return VirtualMemoryView{&layout_, page_table_.view(), cache, misses_.view(), source_->has_labels(), {}};
}

// With device memory: first the page-table words changed this frame (each once, with its current
// value), then the cast; the misses and slot usage it copies back go into the host's miss buffer and
// usage stamps, where miss resolution, the tree's usage and LRU read them exactly as after a CPU cast.
void Residency::cast(const CastRequest& r, Frame& frame) {
  CastFeedback fb;
  if (!device_memory_) {
    device_->cast(r, frame, fb);
    return;
  }
  sync_device_page_table();
  device_->cast(r, frame, fb);
  take_feedback(fb, r.frame);
}

void Residency::sync_device_page_table() {
  PageTableUpdate& u = changed_words_;
  gather_words(u.dir_index, u.dir_value, [&](std::uint32_t i) { return page_table_.directory_word(i); });
  gather_words(u.pool_index, u.pool_value, [&](std::uint64_t i) { return page_table_.pool_word(i); });
  device_->sync_page_table(u);
  u.clear();
}

void Residency::take_feedback(const CastFeedback& fb, std::uint32_t frame) {
  const MissBufferView mv = misses_.view();
  for (const BrickId id : fb.misses) mv.insert(id);
  const BrickCacheView cv = cache_.view();
  for (const std::uint32_t slot : fb.used_slots) {
    if (slot < cache_.slot_count() && cache_.brick_in(slot).valid()) cv.touch(slot, frame);
  }
}

}  // namespace sl
