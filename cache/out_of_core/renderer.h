// The out-of-core, ray-guided frame loop (DESIGN.md "Virtual memory" and "Occupancy histogram tree";
// paper §8.2–§8.3): the caster reads through the page table and brick cache; the misses it reports
// drive metadata, culling, the lazy growth of the occupancy tree and brick loading; usage drives LRU
// eviction and tree retirement. Each concern is its own part: Residency (page table, cache, loader,
// device), LazyOccupancy (tree and metadata), CachePressure (level of detail), Prefetch and
// Convergence; the renderer runs a frame as a list of steps over them.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "cache/brick.h"
#include "cache/out_of_core/cache_pressure.h"
#include "cache/out_of_core/cast_device.h"
#include "cache/out_of_core/convergence.h"
#include "cache/out_of_core/depth_passes.h"
#include "cache/out_of_core/lazy_occupancy.h"
#include "cache/out_of_core/prefetch.h"
#include "cache/out_of_core/residency.h"
#include "cache/out_of_core/settings.h"
#include "cache/out_of_core/tight_boxes.h"
#include "cache/volume_source.h"
#include "core/cast/sample_clip.h"
#include "core/frame/pipeline.h"
#include "core/occupancy/occupancy_tree.h"

namespace sl {

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

  // Nothing left to load or resolve, and no depth pass still to cast (depth_passes.h).
  bool converged() const { return convergence_.converged() && !passes_.in_progress(); }
  // Quarter-octave steps by which cache pressure coarsens the level of detail now (0: none; --lod N: 0).
  int pressure() const { return pressure_.pressure(); }
  std::uint32_t frame() const { return frame_; }
  const OccupancyTree& tree() const { return occupancy_.tree(); }
  const BrickLayout& layout() const { return residency_.layout(); }
  std::size_t metadata_blocks() const { return occupancy_.metadata().size(); }
  std::size_t metadata_capacity() const { return occupancy_.metadata().capacity(); }
  std::uint64_t metadata_evictions() const { return occupancy_.metadata().evictions(); }
  // Level-0 culling blocks whose metadata exists inside the world box (tests: unseen regions have none).
  std::size_t metadata_blocks_in(const Box3& box) const { return occupancy_.metadata_blocks_in(box); }
  std::size_t resident_bricks() const { return residency_.cache().resident_count(); }
  std::size_t failed_bricks() const { return residency_.loader().failed_count(); }
  void wait_for_loads() { residency_.loader().wait_idle(); }
  const CastDevice& device() const { return residency_.device(); }
  // Distributed (DESIGN.md "Beyond one machine"): cast only the samples of this rank's region
  // (core/cast/sample_clip.h); the tree, metadata and bricks then grow only where those samples are.
  // Default: every sample.
  void set_sample_clip(const SampleClip& clip) { clip_ = clip; }
  // Builds the SparseLeap lists instead of build_segment_lists (e.g. the GL builder, `--lists gl`).
  void set_list_builder(ListBuilder builder) { pipeline_.set_list_builder(std::move(builder)); }
  // The host's page-table entry of a brick (tests compare a device's mirror with it).
  PageEntry page_entry(BrickId id) const { return residency_.page_table().get(id); }
  const PageTable& page_table() const { return residency_.page_table(); }
  // Slot of the brick cache holding `id`, if resident; the brick in a slot; a slot's usage stamp.
  std::uint32_t slot_count() const { return residency_.cache().slot_count(); }
  BrickId brick_in_slot(std::uint32_t slot) const { return residency_.cache().brick_in(slot); }
  std::uint32_t slot_last_used(std::uint32_t slot) const { return residency_.cache().last_used(slot); }
  std::uint64_t evictions() const { return residency_.cache().evictions(); }
  // Of the last frame's NON_EMPTY leaf boxes: shrunk to their slots' set cells (tight_boxes.h), and
  // left whole (bricks not resident, or samples straddling levels). Both 0 without tight boxes.
  std::size_t tight_boxes_shrunk() const { return tight_shrunk_; }
  std::size_t tight_boxes_kept() const { return tight_kept_; }

 private:
  // What resolving the misses found: bricks known non-empty and not resident, how many of them were
  // requested (the rest wait for room), and whether anything changed (a request, a mapping, metadata).
  struct MissResolution {
    std::size_t loadable = 0;
    std::size_t requested = 0;
    bool changed = false;
  };
  // The cache's state as the frame began.
  struct FrameStart {
    std::uint64_t evictions = 0;
    bool waiting = false;  // the frame's own loads were in flight
  };
  // The steps of render(), in order.
  void validate(const RenderSettings& s) const;
  void begin_culling(const OutOfCoreScene& scene, const RenderSettings& s);
  // Resets the per-frame counts of every part and notes the cache's state as the frame begins.
  FrameStart start_frame(const OutOfCoreScene& scene, const RenderSettings& s);
  MissResolution answer_last_frame();
  // (loads_and_misses.cpp)
  void make_loads_resident();
  void take_loaded_brick(LoadedBrick&& b, LazyOccupancy::BrickMetadata* computed);
  MissResolution resolve_misses();
  // Loads a miss asks for: for metadata (always made), for data (as far as there is room), and per
  // data load whether its metadata refine a coarser NON_EMPTY leaf.
  struct MissLoads {
    std::vector<BrickId> metadata, data;
    std::vector<bool> refines;
  };
  void resolve_miss(BrickId id, MissResolution& res, MissLoads& loads);
  void request_loads(MissLoads& loads, MissResolution& res);
  float load_priority(BrickId id) const;
  void order_by_priority(std::vector<BrickId>& ids, std::vector<bool>* with) const;
  SkipInputs skip_inputs(const RenderSettings& s, const RayGenerator& gen, const FrameLod& lod, Stats& st);
  void cast(const OutOfCoreScene& scene, const RenderSettings& s, const RayGenerator& gen, const FrameLod& lod,
            const SkipInputs& skip, Frame& frame);
  void touch_used_bricks();
  // (cache_stats.cpp)
  void fill_cache_stats(const FrameStart& start, const FrameLod& lod, Stats& st);
  void count_used_slots(CacheStats& c);
  void count_loader(CacheStats& c) const;
  void count_completeness(Stats& st) const;
  void count_misses(CacheStats& c) const;
  void update_convergence(const MissResolution& resolved, const RayGenerator& gen, CacheStats& c);
  void update_depth_passes(const RayGenerator& gen, CacheStats& c);
  void prefetch(const OutOfCoreScene& scene, const RenderSettings& s, const FrameLod& lod, const RayGenerator& gen,
                const CacheStats& c);

  std::shared_ptr<const VolumeSource> source_;
  OutOfCoreSettings settings_;
  int block_ = 16;
  std::uint32_t frame_ = 0;
  Residency residency_;
  LazyOccupancy occupancy_;
  CachePressure pressure_;
  Prefetch prefetch_;
  Convergence convergence_;
  DepthPasses passes_;
  std::vector<std::uint64_t> shortfall_;  // the frame's SampleShortfall counters (completeness)
  FramePipeline pipeline_;
  TightBoxes tight_;
  OccupancyGeometry tight_geometry_;  // this frame's tight boxes (the lists' boxes)
  std::size_t tight_shrunk_ = 0, tight_kept_ = 0;
  bool masks_ = false;  // the slots' voxel masks are built for this frame (Residency::update_masks)
  SampleClip clip_;
  CullParams cull_;  // this frame's culling inputs (the voxel masks are built for them)
  // Whether the values of bricks culled empty reach the image: iso mode (which side of the iso value
  // a corner or sample lies on) and lighting (the gradient of a sample next to such a brick). Then
  // such a brick is loaded when a ray reads it instead of being mapped Empty (served as 0).
  bool empty_values_read_ = false;
  RayGenerator last_gen_;  // the rays of the frame whose misses are resolved next (load priority)
};

}  // namespace sl
