// Asynchronous brick loading (DESIGN.md §4): worker threads read bricks from a VolumeSource into host
// staging buffers; each frame the renderer collects at most its upload budget of finished bricks and
// never waits for a load. Dedicated std::threads rather than TBB tasks: reads may block on I/O for
// long, and must neither stall nor be starved by the ray caster's parallel loops on the TBB pool
// (the procedural source's coarse bricks still use TBB inside a read, which is compute-bound).
#pragma once

#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <thread>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "cache/brick.h"
#include "cache/volume_source.h"

namespace sl {

struct LoadedBrick {
  BrickId id;
  std::vector<std::byte> intensity;  // stored_voxels * voxel_size(desc().type)
  std::vector<std::byte> labels;     // empty when the source has no labels
};

struct BrickFailure {
  BrickId id;
  std::string reason;  // "<source name>: level 1 brick (2, 0, 3): <what the source said>"
  std::string cause;   // what the source said: the same for every brick one fault (a chunk) covers
};

struct LoaderBatch {
  std::vector<LoadedBrick> bricks;     // at most the requested budget, oldest request first
  std::vector<BrickFailure> failures;  // each failed brick appears exactly once, ever
};

class BrickLoader {
 public:
  // threads = 0: min(4, hardware threads).
  BrickLoader(std::shared_ptr<const VolumeSource> source, const BrickLayout& layout, int threads = 0);
  ~BrickLoader();  // drops queued work, finishes reads in flight, joins the workers
  BrickLoader(const BrickLoader&) = delete;
  BrickLoader& operator=(const BrickLoader&) = delete;

  // Queues the ids that are not already queued, loading, finished-but-uncollected or failed; a failed
  // brick is never retried. Returns how many were queued. Never blocks on loading.
  std::size_t request(std::span<const BrickId> ids);
  // Finished bricks (up to max_bricks) and new failures. Never blocks on loading.
  LoaderBatch collect(std::size_t max_bricks);
  // Drops queued requests not yet started (e.g. after the camera moved away); returns how many.
  std::size_t cancel_queued();
  // Returns a collected brick's buffers for reuse by later loads (optional; avoids reallocation).
  void recycle(LoadedBrick&& brick);

  bool failed(BrickId id) const;
  std::size_t failed_count() const;
  // Queued + loading + finished-but-uncollected.
  std::size_t pending() const;
  std::uint64_t loads_completed() const;
  // Blocks until nothing is queued or loading (tests and benchmarks only).
  void wait_idle();

 private:
  void work();

  std::shared_ptr<const VolumeSource> source_;
  BrickLayout layout_;
  mutable std::mutex mutex_;
  std::condition_variable wake_, idle_;
  struct Job {
    std::uint64_t seq;  // request order: collect hands out the oldest request first
    BrickId id;
  };
  struct Done {
    std::uint64_t seq;
    LoadedBrick brick;
  };
  std::deque<Job> queue_;
  std::uint64_t next_seq_ = 0;
  std::unordered_set<BrickId, BrickIdHash> known_;  // queued, loading or finished-uncollected
  std::unordered_map<BrickId, std::string, BrickIdHash> failed_;
  std::vector<Done> done_;
  std::vector<BrickFailure> new_failures_;
  std::vector<LoadedBrick> spare_;           // recycled buffers
  std::size_t loading_ = 0;
  std::uint64_t completed_ = 0;
  bool stop_ = false;
  std::vector<std::thread> workers_;
};

}  // namespace sl
