// Residency (DESIGN.md "Virtual memory"): which bricks are where. Owns the host's master page table,
// the brick cache (slots and LRU), the miss buffer the caster fills, the loader, and the cast device
// (cast_device.h) with what must reach its memory — the bricks made resident this frame and the
// page-table words changed since the last cast.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <unordered_set>
#include <vector>

#include "cache/brick.h"
#include "cache/brick_cache.h"
#include "cache/brick_loader.h"
#include "cache/miss_buffer.h"
#include "cache/out_of_core/cast_device.h"
#include "cache/out_of_core/settings.h"
#include "cache/page_table.h"
#include "cache/volume_source.h"
#include "core/occupancy/culling.h"

namespace sl {

class Residency {
 public:
  // Throws InputError for a cache too small for one brick per level. `block`: the culling block, whose
  // bounds the loader reads with each coarse brick. `device`: null for the CPU caster on the host's
  // own tables.
  Residency(std::shared_ptr<const VolumeSource> source, const BrickLayout& layout, const OutOfCoreSettings& settings,
            int block, std::unique_ptr<CastDevice> device);
  // Tells the device the geometry its memory must hold (once, after the renderer checked its input).
  void configure_device();

  // Every page-table change goes through here, so a device mirror receives only the changed words.
  void set_page_entry(BrickId id, PageEntry e);
  // Maps a brick Empty because culling found its region empty; forget_culled_empty_pages unmaps
  // those still Empty when the culling changes.
  void map_culled_empty(BrickId id);
  void forget_culled_empty_pages();

  // Counts this frame's loads from zero; with device memory, last frame's uploads have landed.
  void begin_frame();
  // Warns once per cause about a brick that failed to load (one corrupt chunk under many bricks is
  // one warning, not one per brick).
  void report_failure(const BrickFailure& f);
  struct Placement {
    bool placed = false;  // the brick took a slot
    BrickId evicted;      // the brick that held it (invalid: the slot was free)
  };
  // Makes a loaded brick resident in a slot the last frame (frame - 1) did not use: copied into the
  // host slot, or staged for the device. A prefetched brick is stamped older than the last frame, so
  // it is the first room a frame's own load may take. Not placed when already resident or when
  // every slot holds a brick the last frame used. The buffers go back to the loader.
  Placement place(LoadedBrick&& b, std::uint32_t frame, bool prefetched);
  // Sends the bricks staged this frame to the device (device memory only).
  void finish_uploads();
  // Slots a load may take without evicting a brick the last frame used: neither used by the last
  // cast nor filled this frame (those bricks are wanted now), less the loads already on their way.
  std::size_t free_slots_for_loads() const;
  std::uint64_t loads_this_frame() const { return loads_this_frame_; }
  // The slots the last cast used (counted with the frame's stats).
  std::size_t slots_used_last() const { return slots_used_last_; }
  void set_slots_used_last(std::size_t n) { slots_used_last_ = n; }

  // Brings every resident slot's voxel mask up to date with the culling inputs `cull` (key: their
  // cull_key): slots refilled since, or built under other inputs, are built again (parallel over
  // slots). False, building nothing, where masks do not apply: a device with its own memory, a voxel
  // type without masks, a mode other than DVR and labels, or `linear` false (a B-spline filter reads
  // voxels beyond the trilinear cell).
  bool update_masks(const CullParams& cull, std::uint64_t key, bool linear);
  // What a caster sharing host memory reads: the host's own tables; with `masks` the slots' voxel
  // masks (only after update_masks returned true for this frame's culling).
  VirtualMemoryView host_view(bool masks = false);
  // Casts on the device; with device memory, the changed page-table words go first and the misses
  // and slot usage it copies back land in the host's miss buffer and usage stamps.
  void cast(const CastRequest& request, Frame& frame);

  const VolumeSource& source() const { return *source_; }
  const BrickLayout& layout() const { return layout_; }
  const PageTable& page_table() const { return page_table_; }
  const BrickCache& cache() const { return cache_; }
  BrickCache& cache() { return cache_; }
  const MissBuffer& misses() const { return misses_; }
  MissBuffer& misses() { return misses_; }
  const BrickLoader& loader() const { return loader_; }
  BrickLoader& loader() { return loader_; }
  const CastDevice& device() const { return *device_; }

 private:
  void copy_to_host_slot(const LoadedBrick& b, std::uint32_t slot);
  void build_mask(std::uint32_t slot, const VoxelMaskBuilder& builder, bool labels);
  void stage_upload(LoadedBrick&& b, std::uint32_t slot);
  void sync_device_page_table();
  void take_feedback(const CastFeedback& fb, std::uint32_t frame);

  std::shared_ptr<const VolumeSource> source_;
  BrickLayout layout_;
  PageTable page_table_;
  BrickCache cache_;
  MissBuffer misses_;
  BrickLoader loader_;
  std::unique_ptr<CastDevice> device_;
  bool device_memory_ = false;  // the device keeps its own copies (uploads, page-table sync, feedback)
  PageTableUpdate changed_words_;     // page-table words changed since the last sync
  std::vector<BrickUpload> uploads_;  // this frame's new resident bricks (device memory)
  std::vector<LoadedBrick> staged_;   // their buffers, recycled once uploaded
  std::vector<BrickId> culled_empty_pages_;           // entries set Empty by culling
  std::unordered_set<std::string> reported_causes_;  // load failures reported so far
  std::uint64_t loads_this_frame_ = 0;
  std::size_t slots_used_last_ = 0;
};

}  // namespace sl
