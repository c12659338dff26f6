// Where the out-of-core ray caster runs (DESIGN.md "Virtual memory"; paper §8.2–§8.3). The
// OutOfCoreRenderer keeps the master page table, the slot allocation and LRU (residency.h), the miss
// resolution and the occupancy tree (lazy_occupancy.h) on the host; a CastDevice casts each frame and
// reports its misses and slot usage back. Three of them:
//  - CpuCastDevice: the CPU caster reads the host's own page table, cache and miss buffer (zero-copy);
//  - SimulatedCastDevice (simulated_cast_device.h): a CPU stand-in for a GPU with its own copies of
//    page table, slot pool, miss buffer and usage stamps, fed only by uploads — what the tests use to
//    prove the host side of the CUDA backend without a GPU;
//  - the CUDA device (cuda/cuda_cast_device.h): the same protocol with device memory and kernels.
//
// Protocol for a device with its own memory, once per frame:
//   begin_frame()            the uploads issued last frame have landed (a stream synchronisation);
//                            page-table words that pointed at them become visible now
//   upload_bricks(new)       only the bricks made resident this frame; the bytes are copied (staged)
//                            before the call returns, the slot is written asynchronously
//   sync_page_table(dirty)   only the page-table words changed since the last sync. Words that map a
//                            brick to a slot whose upload is still in flight are held back until the
//                            next begin_frame (split_page_table_update), so a kernel never reads a
//                            slot while it is being written; everything else applies before the cast
//   cast(request, feedback)  casts, then copies back once: the distinct missed brick ids and the
//                            slots sampled this frame. The host resolves them with the same code as
//                            for the CPU caster (residency.h, loads_and_misses.cpp).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "cache/brick.h"
#include "cache/brick_cache.h"
#include "cache/miss_buffer.h"
#include "cache/page_table.h"
#include "cache/virtual_sampler.h"
#include "core/cast/cast_pixel.h"
#include "core/frame/frame.h"

namespace sl {

// Everything a sampler needs to read the virtual memory: layout, page table, slot pool, miss buffer.
struct VirtualMemoryView {
  const BrickLayout* layout = nullptr;
  PageTableView page_table;
  BrickCacheView cache;
  MissBufferView misses;
  bool has_labels = false;
  SampleShortfall shortfall;  // completeness counters (host memory; null: not counted)
};

// Fixed once per renderer.
struct DeviceConfig {
  BrickLayout layout{};
  VoxelType voxel_type = VoxelType::U8;
  bool has_labels = false;
  VoxelType label_type = VoxelType::U32;
  std::uint32_t slot_count = 0;
  std::uint32_t miss_capacity = 1u << 16;
  PageTableView page_table_geometry;  // level geometry (directory offsets, page grids); pointers null
  std::size_t directory_words = 0;
};

// The caster's view of a device's slot pool: the same fields whatever memory holds the slots (the CPU
// stand-in's vectors, CUDA allocations). label_stride 0 means no labels.
inline BrickCacheView device_cache_view(const DeviceConfig& config, std::byte* voxels, std::byte* labels,
                                        std::uint32_t* usage, std::uint64_t voxel_stride,
                                        std::uint64_t label_stride) {
  BrickCacheView c;
  c.voxels = voxels;
  c.labels = label_stride ? labels : nullptr;
  c.usage = usage;
  c.voxel_stride = voxel_stride;
  c.label_stride = label_stride;
  c.slot_count = config.slot_count;
  c.stored = config.layout.stored_size();
  c.voxel_type = config.voxel_type;
  c.label_type = config.label_type;
  c.has_labels = label_stride ? 1 : 0;
  return c;
}

struct BrickUpload {
  std::uint32_t slot = 0;
  BrickId id;
  std::span<const std::byte> voxels;  // stored_voxels() voxels of the intensity type
  std::span<const std::byte> labels;  // same for labels; empty without
};

// Splits `u` into the words to apply now and those that map a brick to a slot still being uploaded
// (in_flight[slot]); the latter go to `later`, applied after the uploads land (order kept: later
// words of the next update overwrite them).
void split_page_table_update(const PageTableUpdate& u, const std::vector<bool>& in_flight, PageTableUpdate& now,
                             PageTableUpdate& later);

struct CastRequest {
  CastParams params;  // host pointers (transfer-function table, label bits)
  RayGenerator gen;
  Box3 vbox;
  SkipInputs skip;    // host views (segment lists)
  std::uint32_t frame = 0;
  VirtualMemoryView host;  // the host's own tables: used only by a device that shares host memory
};

struct CastFeedback {
  std::vector<BrickId> misses;            // distinct ids reported this frame (sorted)
  std::vector<std::uint32_t> used_slots;  // slots sampled this frame
};

class CastDevice {
 public:
  virtual ~CastDevice() = default;
  virtual const char* name() const = 0;
  // True: the caster reads the host's page table, cache and miss buffer directly (the CPU): no
  // uploads, no page-table sync, misses and usage land in the host buffers during the cast.
  virtual bool shares_host_memory() const = 0;
  // True: the cast runs on the host and may read and write per-ray state in host memory
  // (SkipInputs::rays: depth passes, depth_passes.h). The CPU and its simulated stand-in; not a GPU.
  virtual bool casts_on_host() const { return shares_host_memory(); }
  virtual void configure(const DeviceConfig& config) = 0;
  virtual void begin_frame() = 0;
  virtual void upload_bricks(std::span<const BrickUpload> bricks) = 0;
  virtual void sync_page_table(const PageTableUpdate& update) = 0;
  // Fills frame.image (sized by the caller) and the ray-casting stats, as cast_frame does.
  virtual void cast(const CastRequest& request, Frame& frame, CastFeedback& feedback) = 0;
};

// A device with its own memory counts the frame's sample shortfall (virtual_sampler.h, the CPU's own
// code) into its own SampleShortfall::kWords counters, zeroed before the cast; the host adds them into
// the frame's counters, so completeness and lod_coarsened are the CPU's on every device. A null host
// counter array means the frame does not count.
void add_shortfall(const SampleShortfall& host, std::span<const std::uint64_t> device);

// The CPU caster over a virtual memory view (type dispatch + cast_frame); every CPU device uses it.
void cast_virtual_frame(const CastParams& params, const RayGenerator& gen, const Box3& vbox, const SkipInputs& skip,
                        std::uint32_t frame_number, const VirtualMemoryView& vm, Frame& frame);

class CpuCastDevice final : public CastDevice {
 public:
  const char* name() const override { return "cpu"; }
  bool shares_host_memory() const override { return true; }
  void configure(const DeviceConfig&) override {}
  void begin_frame() override {}
  void upload_bricks(std::span<const BrickUpload>) override {}
  void sync_page_table(const PageTableUpdate&) override {}
  void cast(const CastRequest& r, Frame& frame, CastFeedback&) override {
    cast_virtual_frame(r.params, r.gen, r.vbox, r.skip, r.frame, r.host, frame);
  }
};

}  // namespace sl
