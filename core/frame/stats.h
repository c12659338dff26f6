// One stats struct filled by every stage and printed by every front end (STYLE.md #10).
#pragma once

#include <chrono>
#include <cstdint>
#include <string>

namespace sl {

struct StageTimes {
  double total = 0, metadata = 0, tree = 0, geometry = 0, order = 0, lists = 0, raycast = 0;
};

// Out-of-core counters of a frame (present only on the out-of-core path).
struct CacheStats {
  bool present = false;
  std::uint32_t frame = 0;
  double resident_mb = 0;
  std::uint64_t hits = 0;        // distinct resident bricks used this frame
  std::uint64_t misses = 0;      // distinct bricks reported missing this frame (unified misses)
  std::uint64_t loads = 0;       // bricks made resident this frame
  std::uint64_t evictions = 0;   // bricks evicted this frame
  std::uint64_t pending = 0;     // the frame's own loads in flight (prefetches not included)
  // Prefetch (OutOfCoreSettings::prefetch): bricks made resident by prefetch this frame, prefetched
  // bricks sampled for the first time this frame, prefetches in flight.
  std::uint64_t prefetched = 0;
  std::uint64_t prefetch_hits = 0;
  std::uint64_t prefetch_pending = 0;
  // A stall: the frame began with its own loads in flight and made none resident.
  bool stall = false;
  std::uint64_t failed = 0;      // bricks that failed to load (reported once each)
  // Transient read failures retried with backoff, like `failed` counted since the first
  // frame: bricks retried, retry reads, and retried bricks that then loaded.
  std::uint64_t bricks_retried = 0;
  std::uint64_t retries = 0;
  std::uint64_t recovered = 0;
  std::uint64_t page_table_bytes = 0;  // page-table memory held (directory, chunks, bookkeeping)
  int converged_at_frame = -1;   // first frame with nothing left to load or resolve (-1: not yet)
  // Cache pressure (DESIGN.md "Virtual memory"): share of samples served at the level chosen for them (after any
  // coarsening), share coarser than the pixel footprint asks because of pressure, bricks wanted
  // but not resident; and the view's working set at the footprint's level, measured from the frame's
  // requests, when it exceeds the cache (0 otherwise).
  double completeness = 1.0;
  double lod_coarsened = 0.0;
  // Samples the bricks' voxel masks and fine cells left out (they contribute nothing; not in
  // Stats::samples, which counts the samples taken).
  std::uint64_t samples_left_out = 0;
  std::uint64_t bricks_missing = 0;
  double working_set_mb = 0;
  int working_set_level = 0;
  double cache_mb = 0;           // the cache's budget in use (slots x slot size)
  // Bricks the cache holds at most, and the bytes of one: voxels with apron, labels when the frame
  // can show them, the voxel mask.
  std::uint64_t slots = 0;
  std::uint64_t slot_bytes = 0;
  // Depth passes (cache/out_of_core/depth_passes.h: a pinned level whose working set does not fit):
  // their number (0: one pass), the one this frame cast, and the rays' states they hold.
  int depth_passes = 0;
  int depth_pass = 0;
  std::uint64_t depth_pass_bytes = 0;
};

struct Stats {
  int width = 0;
  int height = 0;
  std::string backend = "cpu";
  std::string method;
  std::string mode;
  StageTimes time_ms;
  std::uint64_t samples = 0;            // samples taken, all rays
  std::uint64_t useful_samples = 0;     // samples that contributed (opacity > 0)
  std::uint64_t rays = 0;               // rays that met the volume box
  std::uint64_t boxes = 0;              // occupancy-geometry boxes
  std::uint64_t events = 0;             // ray events in all segment lists
  std::uint64_t occupancy_misses = 0;   // UNKNOWN segments sampled
  std::uint64_t list_overflows = 0;     // pixels whose list hit a fixed capacity (GL lists only)
  std::uint64_t list_bytes = 0;         // storage of the frame's segment lists (events, offsets, counts)
  std::uint64_t list_tile_entries = 0;  // CPU list builder's work: visibility entries met per screen tile
  std::uint64_t list_slab_tests = 0;    // and (box, pixel) slab tests (0 for other builders)
  std::uint64_t metadata_blocks = 0;    // blocks whose metadata exists
  std::uint64_t metadata_computed = 0;  // blocks whose metadata was computed this frame (in or out of core)
  std::uint64_t metadata_bytes = 0;     // memory of the block metadata held (out of core; bounded, LRU)
  std::uint64_t tree_nodes = 0;
  std::uint64_t tree_bytes = 0;         // occupancy-tree memory held (node pool, free list)
  double depth_complexity_avg = 0;      // segments (SparseLeap) / nodes (octree) per ray
  std::uint32_t depth_complexity_max = 0;
  std::uint32_t depth_complexity_min = 0;
  CacheStats cache;
};

// A frame's ray-casting counters, as the CPU tile loop (core/frame/cast_tiles.h) and the CUDA kernels
// (cuda/cast_kernels.cuh) sum them over its pixels.
struct CastCounters {
  std::uint64_t samples = 0, useful = 0, rays = 0, misses = 0, dc_sum = 0;
  std::uint32_t dc_max = 0, dc_min = 0xFFFFFFFFu;

  // From any set of counters with these field names (the CPU loop's atomics, the device's copy).
  template <class C>
  static CastCounters from(const C& c) {
    CastCounters r;
    r.samples = c.samples;
    r.useful = c.useful;
    r.rays = c.rays;
    r.misses = c.misses;
    r.dc_sum = c.dc_sum;
    r.dc_max = c.dc_max;
    r.dc_min = c.dc_min;
    return r;
  }
};

// The one place the ray-casting part of Stats is filled from the counters, for every backend. Depth
// complexity only with skipping (segments or octree nodes per ray; no skipping has none).
void record_cast_counters(const CastCounters& c, bool skipping, Stats& st);

std::string stats_to_json(const Stats& s);
// One line for people: size, backend, method, milliseconds, samples.
std::string stats_summary(const Stats& s);

class Timer {
 public:
  Timer() : start_(std::chrono::steady_clock::now()) {}
  double ms() const {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start_).count();
  }

 private:
  std::chrono::steady_clock::time_point start_;
};

}  // namespace sl
