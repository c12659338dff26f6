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
#include "cache/metadata_cache.h"
#include "cache/miss_buffer.h"
#include "cache/page_table.h"
#include "cache/volume_source.h"
#include "core/occupancy/block_metadata.h"
#include "core/frame/pipeline.h"
#include "core/occupancy/occupancy_tree.h"
#include "core/cast/sample_clip.h"

namespace sl {

struct OutOfCoreSettings {
  int brick = kDefaultBrickSize;     // payload edge B (the culling block must not exceed it)
  std::size_t cache_mb = 1024;       // brick cache budget
  float lod_bias = 1.0f;             // > 1: coarser levels (fewer bricks), < 1: finer
  int lod = -1;                      // >= 0: pin every sample to this level
  std::uint32_t retire_frames = 60;  // tree nodes unused this long are retired (LRU)
  std::size_t upload_budget = 512;   // bricks made resident per frame at most
  int loader_threads = 0;            // 0: min(4, cores)
  RetryPolicy retry;                 // transient read failures (brick_loader.h)
  // Prefetch (issue 14): once a frame has every brick it asked for, load within the upload budget
  // and the cache's spare room the next-finer level around the view's focus and, given the next
  // camera (OutOfCoreScene::next_camera), the bricks that view will want finer. Prefetched bricks
  // never evict a brick the last frame used and are the first to go when a frame needs the room.
  bool prefetch = false;
  // Block metadata kept at most (least recently used dropped, cache/metadata_cache.h); 0: four
  // times the culling blocks of the bricks the cache holds, at least 16,384 blocks.
  std::size_t metadata_blocks = 0;
};

struct OutOfCoreScene {
  const TransferFunction* tf = nullptr;
  const LabelSet* enabled = nullptr;  // label mask (dvr/mip/iso) or the shown set (labels mode)
  Camera camera;
  const Camera* next_camera = nullptr;  // the view expected next (prefetch along the motion); optional
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
  // Quarter-octave steps by which cache pressure coarsens the level of detail now (0: none; --lod N: 0).
  int pressure() const { return pressure_; }
  std::uint32_t frame() const { return frame_; }
  const OccupancyTree& tree() const { return tree_; }
  const BrickLayout& layout() const { return layout_; }
  std::size_t metadata_blocks() const { return metadata_.size(); }
  std::size_t metadata_capacity() const { return metadata_.capacity(); }
  std::uint64_t metadata_evictions() const { return metadata_.evictions(); }
  // Level-0 culling blocks whose metadata exists inside the world box (tests: unseen regions have none).
  std::size_t metadata_blocks_in(const Box3& box) const;
  std::size_t resident_bricks() const { return cache_.resident_count(); }
  std::size_t failed_bricks() const { return loader_.failed_count(); }
  void wait_for_loads() { loader_.wait_idle(); }
  const CastDevice& device() const { return *device_; }
  // Distributed (DESIGN.md §11): cast only the samples of this rank's region (core/cast/sample_clip.h);
  // the tree, metadata and bricks then grow only where those samples are. Default: every sample.
  void set_sample_clip(const SampleClip& clip) { clip_ = clip; }
  // Builds the SparseLeap lists instead of build_segment_lists (e.g. the GL builder, `--lists gl`).
  void set_list_builder(ListBuilder builder) { pipeline_.set_list_builder(std::move(builder)); }
  // The host's page-table entry of a brick (tests compare a device's mirror with it).
  PageEntry page_entry(BrickId id) const { return page_table_.get(id); }
  const PageTable& page_table() const { return page_table_; }
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
  // Computes (and caches) the metadata of a loaded brick's culling blocks; `apply`: classes them in
  // the tree now (a prefetched brick's wait until a frame first samples it).
  void compute_metadata(const LoadedBrick& b, const Cull& cull, bool apply = true);
  // Culling block c of `level` (a key of metadata_) as a region of the tree: node depth levels() - l
  // covering level-0 blocks [c * 2^l, (c + 1) * 2^l).
  RegionClass region(int level, ivec3 c, OccupancyClass cls) const;
  void set_region(const RegionClass& r);  // sets the class and marks the node used this frame
  RegionClass culled_region(std::uint64_t key, const BlockMetadata& m, const Cull& cull) const;
  // Provisional coarse EMPTY (metadata a source could not bound) where this frame's level of detail
  // wants a finer level: opened, i.e. NON_EMPTY from now on. Returns whether any opened.
  bool open_provisional(const Cull& cull, const LodParams& lod, const RayGenerator& gen);
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
  // Requests prefetches after a complete frame (settings_.prefetch).
  void prefetch(const OutOfCoreScene& scene, const RenderSettings& s, const LodParams& lod, const RayGenerator& gen,
                const CacheStats& c);

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
  MetadataCache metadata_;                                      // key: BrickId::pack(level, culling block)
  std::unordered_set<std::uint64_t> metadata_pending_;         // bricks requested for their metadata
  // Coarse metadata from the level's own voxels (VolumeSource::bound_blocks declined: a stored
  // pyramid of means, not bounds) culls EMPTY only for samples at its level or coarser; provisional_
  // holds such keys, opened_ those a finer level was wanted in (classed NON_EMPTY, so the finer
  // bricks load and their own metadata refines the tree there).
  std::unordered_set<std::uint64_t> provisional_, opened_;
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
  SampleClip clip_;
  bool device_memory_ = false;  // the device keeps its own copies (uploads, page-table sync, feedback)
  PageTableUpdate dirty_;       // page-table words changed since the last sync
  std::vector<BrickUpload> uploads_;  // this frame's new resident bricks (device memory)
  std::vector<LoadedBrick> staged_;   // their buffers, recycled once uploaded
  // Prefetch: requested and not yet collected (a frame's own request of one makes it demand), and
  // made resident by prefetch but not sampled yet.
  std::unordered_set<BrickId, BrickIdHash> prefetch_requested_, prefetched_unused_;
  // Prefetched bricks whose metadata is cached but not yet in the tree; those a frame sampled, to
  // apply at the next frame.
  std::unordered_set<BrickId, BrickIdHash> unapplied_;
  std::vector<BrickId> apply_next_;
  std::uint64_t prefetched_this_frame_ = 0;
};

}  // namespace sl
