// The out-of-core, ray-guided frame loop (DESIGN.md §4–§5, paper §8.2–§8.3): the CPU caster reads
// through the page table and brick cache; the misses it reports drive metadata, culling, the lazy
// growth of the occupancy tree and brick loading; usage drives LRU eviction and tree retirement.
#pragma once

#include <cstdint>
#include <memory>
#include <unordered_map>
#include <string>
#include <unordered_set>
#include <vector>

#include "cache/brick.h"
#include "cache/brick_cache.h"
#include "cache/brick_loader.h"
#include "cache/cast_device.h"
#include "cache/miss_buffer.h"
#include "cache/page_table.h"
#include "cache/volume_source.h"
#include "core/block_metadata.h"
#include "core/frame_pipeline.h"
#include "core/occupancy_tree.h"

namespace sl {

struct OutOfCoreSettings {
  int brick = kDefaultBrickSize;     // payload edge B (the culling block must not exceed it)
  std::size_t cache_mb = 1024;       // brick cache budget
  float lod_bias = 1.0f;             // > 1: coarser levels (fewer bricks), < 1: finer
  int lod = -1;                      // >= 0: pin every sample to this level
  std::uint32_t retire_frames = 60;  // tree nodes unused this long are retired (LRU)
  std::size_t upload_budget = 512;   // bricks made resident per frame at most
  int loader_threads = 0;            // 0: min(4, cores)
};

struct OutOfCoreScene {
  const TransferFunction* tf = nullptr;
  const LabelSet* enabled = nullptr;  // label mask (dvr/mip/iso) or the shown set (labels mode)
  Camera camera;
};

class OutOfCoreRenderer {
 public:
  // Throws InputError for a cache too small for one brick per level, bad brick/block sizes.
  // `device` casts the frames (cast_device.h); null: the CPU caster on the host's own tables.
  OutOfCoreRenderer(std::shared_ptr<const VolumeSource> source, const OutOfCoreSettings& settings, int block,
                    std::unique_ptr<CastDevice> device = nullptr);
  ~OutOfCoreRenderer();

  // One frame: make finished loads resident, resolve last frame's misses, grow or retire the tree,
  // build the occupancy geometry and segment lists (SparseLeap) and cast. Never waits for loads.
  Frame render(const OutOfCoreScene& scene, const RenderSettings& settings);

  bool converged() const { return converged_; }
  std::uint32_t frame() const { return frame_; }
  const OccupancyTree& tree() const { return tree_; }
  const BrickLayout& layout() const { return layout_; }
  std::size_t metadata_blocks() const { return metadata_.size(); }
  // Level-0 culling blocks whose metadata exists inside the world box (tests: unseen regions have none).
  std::size_t metadata_blocks_in(const Box3& box) const;
  std::size_t resident_bricks() const { return cache_.resident_count(); }
  std::size_t failed_bricks() const { return loader_.failed_count(); }
  void wait_for_loads() { loader_.wait_idle(); }
  const CastDevice& device() const { return *device_; }
  // Builds the SparseLeap lists instead of build_segment_lists (e.g. the GL builder, `--lists gl`).
  void set_list_builder(ListBuilder builder) { pipeline_.set_list_builder(std::move(builder)); }
  // The host's page-table entry of a brick (tests compare a device's mirror with it).
  PageEntry page_entry(BrickId id) const { return page_table_.get(id); }
  // Slot of the brick cache holding `id`, if resident; the brick in a slot; a slot's usage stamp.
  std::uint32_t slot_count() const { return cache_.slot_count(); }
  BrickId brick_in_slot(std::uint32_t slot) const { return cache_.brick_in(slot); }
  std::uint32_t slot_last_used(std::uint32_t slot) const { return cache_.last_used(slot); }
  std::uint64_t evictions() const { return cache_.evictions(); }

 private:
  struct Cull;
  // What resolving the misses found: bricks known non-empty and not resident, how many of them were
  // requested (the rest wait for room), and whether anything changed (a request, a mapping, metadata).
  struct Resolved {
    std::size_t loadable = 0;
    std::size_t requested = 0;
    bool changed = false;
  };
  void upload(const Cull& cull);
  Resolved resolve_misses(const Cull& cull);
  // Coarsens the automatic level of detail when the bricks the last frame wanted do not fit, refines
  // it again when the view has settled and the finer step was not measured too big (DESIGN.md §4).
  void adapt_pressure(const Resolved& r);
  // Slots a load may take without evicting a brick the last frame used.
  std::size_t room() const;
  void compute_metadata(const LoadedBrick& b, const Cull& cull);
  // Culling block c of `level` (a key of metadata_) as a region of the tree: node depth levels() - l
  // covering level-0 blocks [c * 2^l, (c + 1) * 2^l).
  RegionClass region(int level, ivec3 c, OccupancyClass cls) const;
  void set_region(const RegionClass& r);  // sets the class and marks the node used this frame
  RegionClass culled_region(std::uint64_t key, const BlockMetadata& m, const Cull& cull) const;
  void apply_metadata(std::uint64_t key, const BlockMetadata& m, const Cull& cull);
  // Calls fn(c) for the coordinate c (at the brick's level) of each of the (B / block)³ culling
  // blocks of brick `id` that start inside its level.
  template <class Fn> void for_each_culling_block(BrickId id, Fn&& fn) const;
  std::uint32_t node_for_brick(BrickId id) const;
  void recull(const Cull& cull);
  void touch_used_bricks();
  // Every page-table change goes through here, so a device mirror receives only the changed words.
  void map(BrickId id, PageEntry e);
  void cast(const CastRequest& request, Frame& frame);

  std::shared_ptr<const VolumeSource> source_;
  OutOfCoreSettings settings_;
  BrickLayout layout_;
  int block_ = 16;
  int brick_depth_offset_ = 1;  // log2(brick / block)
  PageTable page_table_;
  BrickCache cache_;
  MissBuffer misses_;
  BrickLoader loader_;
  OccupancyTree tree_;
  std::unordered_map<std::uint64_t, BlockMetadata> metadata_;  // key: BrickId::pack(level, culling block)
  std::unordered_set<std::uint64_t> metadata_pending_;         // bricks requested for their metadata
  std::vector<BrickId> empty_entries_;                         // page entries set Empty by culling
  std::unordered_set<std::string> reported_causes_;            // load failures reported so far
  std::uint64_t cull_key_ = 0;
  bool cull_valid_ = false;
  std::uint32_t frame_ = 0;
  bool converged_ = false;
  int converged_at_ = -1;
  std::uint64_t loads_this_frame_ = 0;
  // Cache pressure: the level of detail is coarsened in quarter-octave steps (the pixel footprint is
  // scaled by 2^(pressure / 4)), which first coarsens, within each level's distance band, the
  // samples whose voxels are smallest on screen — where coarsening costs least.
  int pressure_ = 0;
  int overflow_at_ = -1;           // largest step measured too big for the cache in this view
  std::uint64_t view_key_ = 0;     // camera and sampling; a change allows refining again
  std::size_t hits_last_ = 0;      // slots the last cast used
  std::size_t misses_last_ = 0;
  std::size_t need_footprint_ = 0; // bricks the view wanted at pressure 0 when they did not fit
  std::vector<std::uint64_t> shortfall_;  // SampleShortfall counters
  std::uint64_t metadata_computed_this_frame_ = 0;
  std::unique_ptr<CastDevice> device_;
  FramePipeline pipeline_;
  bool device_memory_ = false;  // the device keeps its own copies (uploads, page-table sync, feedback)
  PageTableUpdate dirty_;       // page-table words changed since the last sync
  std::vector<BrickUpload> uploads_;  // this frame's new resident bricks (device memory)
  std::vector<LoadedBrick> staged_;   // their buffers, recycled once uploaded
};

}  // namespace sl
