// Lazy occupancy (DESIGN.md "Virtual memory" and "Occupancy histogram tree"; paper §8.2): the
// occupancy tree starts UNKNOWN and grows only where rays report an occupancy miss, from the metadata
// of the culling blocks a brick holds, computed when the brick first arrives. The metadata stay cached
// (bounded, cache/metadata_cache.h) to regrow retired regions and to re-cull when the classification
// (transfer function, labels, iso value) changes, without touching the data.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <unordered_set>

#include "cache/brick.h"
#include "cache/brick_loader.h"
#include "cache/metadata_cache.h"
#include "cache/volume_source.h"
#include "core/cast/raycast.h"
#include "core/frame/stats.h"
#include "core/occupancy/culling.h"
#include "core/occupancy/occupancy_tree.h"
#include "core/scene/camera.h"

namespace sl {

class LazyOccupancy {
 public:
  // Throws InputError for a bad culling block size or one larger than the brick.
  LazyOccupancy(std::shared_ptr<const VolumeSource> source, const BrickLayout& layout, int block,
                std::size_t metadata_capacity);

  // Starts frame `frame` with its culling inputs. A change rebuilds the tree from the cached metadata
  // (nothing is recomputed or reloaded) and returns true: Empty mappings made under the old culling
  // must be forgotten.
  bool begin_frame(std::uint32_t frame, const CullParams& cull);
  std::uint64_t cull_key() const { return cull_key_; }

  // What the tree says of a brick's region: Unknown when any of it is UNKNOWN, else its class
  // (conservative above the leaves).
  OccupancyClass brick_class(BrickId id) const;
  // Known NON_EMPTY with nothing UNKNOWN below (where a prefetch may load).
  bool known_non_empty(BrickId id) const;
  // Whether the metadata of all the brick's culling blocks are cached.
  bool has_metadata(BrickId id) const;
  // A NON_EMPTY leaf coarser than this brick's culling blocks (known from a coarser level) whose
  // metadata are not cached yet: the brick's own metadata, computed when it arrives, refine the tree
  // as far as the level of detail the rays now ask for.
  bool refined_by_loading(BrickId id) const;

  // Applies the brick's cached metadata to the tree if all of them are cached (regrowing a retired or
  // re-culled region without touching the data); returns whether they were.
  bool apply_cached_metadata_if_complete(BrickId id);
  // Applies those of the brick's culling blocks whose metadata are cached.
  void apply_cached_metadata(BrickId id);
  // Marks a brick as loaded for its metadata; returns false if it already was.
  bool request_metadata(BrickId id);
  // Whether a collected brick was loaded for its metadata (and clears the request).
  bool take_metadata_request(BrickId id);
  bool waiting_for_metadata() const { return !metadata_requested_.empty(); }
  // The metadata of a loaded brick's culling blocks, computed without touching the occupancy (pure,
  // thread-safe: a frame's collected bricks compute theirs on all cores).
  struct BrickMetadata {
    std::vector<ivec3> blocks;
    std::vector<BlockMetadata> metadata;
    bool bounded = false;  // from the source's bounds (else from the brick's voxels, provisional)
  };
  BrickMetadata brick_metadata(const LoadedBrick& b) const;
  // Whether a collected brick was requested for its metadata (take_metadata_request's answer).
  bool metadata_requested(BrickId id) const { return metadata_requested_.count(id.bits) != 0; }
  // Caches (and with `apply` classes in the tree now; a prefetched brick's wait until a frame first
  // samples it) the metadata of a loaded brick's culling blocks: `computed` if given (brick_metadata
  // of the same brick), else computed here.
  void compute_metadata(const LoadedBrick& b, bool apply = true, BrickMetadata* computed = nullptr);
  // A brick that can never load: its region's occupancy can never be known, so it is called
  // NON_EMPTY (conservative; the data read as missing), rays stop reporting occupancy misses there
  // and the view can converge.
  void mark_unreadable(BrickId id);

  // Before the tree is used: opens provisional EMPTY where this frame's level of detail wants a finer
  // level, then propagates and collapses the tree. Returns whether any opened.
  bool update_tree(const LodParams& lod, const RayGenerator& gen);
  // Retires tree nodes unused for `retire_frames` and drops metadata beyond the cache's capacity.
  void retire(std::uint32_t retire_frames);
  // Marks the brick's node and metadata used this frame.
  void touch_brick(BrickId id);
  void fill_stats(Stats& st) const;

  const OccupancyTree& tree() const { return tree_; }
  const MetadataCache& metadata() const { return metadata_; }
  // Level-0 culling blocks whose metadata exists inside the world box.
  std::size_t metadata_blocks_in(const Box3& box) const;

 private:
  // Culling block c of `level` (a key of metadata_) as a region of the tree: node depth levels() - l
  // covering level-0 blocks [c * 2^l, (c + 1) * 2^l).
  RegionClass region(int level, ivec3 c, OccupancyClass cls) const;
  void set_region(const RegionClass& r);  // sets the class and marks the node used this frame
  RegionClass culled_region(std::uint64_t key, const BlockMetadata& m) const;
  void apply_metadata(std::uint64_t key, const BlockMetadata& m);
  bool open_provisional(const LodParams& lod, const RayGenerator& gen);
  bool wants_finer_level(BrickId block, const LodParams& lod, const RayGenerator& gen) const;
  void recull();
  // The metadata of `blocks` (culling blocks of b's level) from the source's bounds, else from the
  // brick's own voxels (`bounded` false).
  std::vector<BlockMetadata> block_metadata(const LoadedBrick& b, const std::vector<ivec3>& blocks,
                                            bool& bounded) const;
  // Calls fn(c) for the coordinate c (at the brick's level) of each of the (B / block)³ culling
  // blocks of brick `id` that start inside its level.
  template <class Fn> void for_each_culling_block(BrickId id, Fn&& fn) const;
  std::uint32_t node_for_brick(BrickId id) const;

  std::shared_ptr<const VolumeSource> source_;
  BrickLayout layout_;
  int block_ = 16;
  OccupancyTree tree_;
  int brick_depth_offset_ = 1;  // log2(brick / block)
  MetadataCache metadata_;                                  // key: BrickId::pack(level, culling block)
  std::unordered_set<std::uint64_t> metadata_requested_;  // bricks requested for their metadata
  // Coarse metadata from the level's own voxels (VolumeSource::bound_blocks declined: a stored
  // pyramid of means, not bounds) culls EMPTY only for samples at its level or coarser; provisional_
  // holds such keys, opened_ those a finer level was wanted in (classed NON_EMPTY, so the finer
  // bricks load and their own metadata refines the tree there).
  std::unordered_set<std::uint64_t> provisional_, opened_;
  CullParams cull_;  // this frame's
  std::uint64_t cull_key_ = 0;
  bool cull_valid_ = false;
  std::uint32_t frame_ = 0;
  std::uint64_t metadata_computed_this_frame_ = 0;
};

}  // namespace sl
