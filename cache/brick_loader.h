// Asynchronous brick loading (DESIGN.md "Virtual memory"): worker threads read bricks from a
// VolumeSource into host staging buffers; each frame the renderer collects at most its upload budget of
// finished bricks and never waits for a load. Dedicated std::threads rather than TBB tasks: reads may
// block on I/O for long, and must neither stall nor be starved by the ray caster's parallel loops on
// the TBB pool (the procedural source's coarse bricks still use TBB inside a read, which is
// compute-bound). A read that fails with a TransientError (timeout, dropped connection, HTTP 5xx) is
// retried with exponential backoff; the backoff is a not-before time on a queue, never a sleeping
// worker.
#pragma once

#include <chrono>
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
  // A level >= 1 brick of a loader given a culling block size: its culling blocks' bounds over the
  // level-0 voxels below (VolumeSource::read_brick_bounded, in brick_culling_blocks order), read in the
  // worker with the brick; empty when the source cannot bound them.
  std::vector<BlockMetadata> bounds;
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

// How TransientErrors are retried. The defaults ride out the outages a remote store typically has
// (an HTTP 503 or a reset connection clears within a second or so): retries after 50, 100, 200 and
// 400 ms, then the brick fails like a permanent error — so a brick that is really gone is settled
// (reported, rendered as missing, the view converges) about 0.75 s after its first read, instead of
// holding the view unconverged. The cap bounds the wait when max_attempts is raised.
struct RetryPolicy {
  int max_attempts = 5;  // reads of one brick at most, the first included (1: never retry)
  std::chrono::milliseconds first_backoff{50};
  std::chrono::milliseconds max_backoff{1000};
  // Wait before attempt `attempt` + 1 (attempt 0 is the first read): first_backoff * 2^attempt, capped.
  std::chrono::milliseconds backoff(int attempt) const;
};

// Retry counts since the loader was made (the frame stats carry them, core/frame/stats.h).
struct LoaderCounts {
  std::uint64_t bricks_retried = 0;  // bricks that failed transiently at least once
  std::uint64_t retries = 0;         // reads repeated after a transient failure
  std::uint64_t recovered = 0;       // bricks that loaded after failing transiently
  std::uint64_t failed = 0;          // bricks failed for good (permanent, or out of attempts)
};

class BrickLoader {
 public:
  // The buffers of finished bricks waiting to be collected are bounded (DESIGN.md "Virtual memory":
  // memory within the budget): while they and the reads in flight hold this many bytes, no worker
  // starts another read. Requests beyond it wait as ids, which cost bytes, not bricks.
  static constexpr std::size_t kDefaultFinishedBytes = std::size_t(256) << 20;

  // threads = 0: min(4, hardware threads). finished_bytes: the bound above (at least one brick per
  // worker is always allowed). bounds_block > 0: coarse bricks come with their culling blocks' bounds
  // (LoadedBrick::bounds; a source that synthesises or reads the level-0 voxels for them does that
  // once, in the worker, not again on the frame's thread).
  BrickLoader(std::shared_ptr<const VolumeSource> source, const BrickLayout& layout, int threads = 0,
              const RetryPolicy& retry = {}, std::size_t finished_bytes = kDefaultFinishedBytes,
              int bounds_block = 0);
  // Drops queued work and waiting retries (without waiting out their backoff), finishes reads in
  // flight, joins the workers.
  ~BrickLoader();
  BrickLoader(const BrickLoader&) = delete;
  BrickLoader& operator=(const BrickLoader&) = delete;

  // Queues the ids that are not already queued, loading, waiting for a retry, finished-but-uncollected
  // or failed; a failed brick is never requested again. The ids given, new or still queued, go ahead of
  // every earlier queued job, in the order given (priority: the caller's first id loads first).
  // Returns how many were queued (a queued prefetch named here counts). Never blocks on loading.
  std::size_t request(std::span<const BrickId> ids);
  // As request, at the lowest priority: a worker starts a prefetch only when no request is queued
  // (prefetch never delays a brick a frame asked for). Requesting a queued prefetch promotes it.
  std::size_t prefetch(std::span<const BrickId> ids);
  // Finished bricks (up to max_bricks) and new failures. Never blocks on loading.
  LoaderBatch collect(std::size_t max_bricks);
  // Drops queued requests not yet started and retries waiting for their backoff (e.g. after the camera
  // moved away); returns how many. A dropped retry starts again from attempt 1 if requested again.
  std::size_t cancel_queued();
  // Returns a collected brick's buffers for reuse by later loads (optional; avoids reallocation).
  void recycle(LoadedBrick&& brick);

  bool failed(BrickId id) const;
  std::size_t failed_count() const;
  // Queued + waiting for a retry + loading + finished-but-uncollected.
  std::size_t pending() const;
  // Reads finished, successful or not (every attempt counts).
  std::uint64_t loads_completed() const;
  LoaderCounts counts() const;
  // Finished bricks the bound lets wait for collect() (and the reads in flight count against it).
  std::size_t finished_capacity() const { return finished_cap_; }
  // Worker threads (the constructor's `threads`, 0 resolved).
  int threads() const { return int(workers_.size()); }
  // Blocks until nothing is queued, waiting for a retry or loading — or until the finished bricks
  // fill their bound, so that only a collect() lets the loader go on.
  void wait_idle();

 private:
  using Clock = std::chrono::steady_clock;
  void work();
  // Moves retries whose backoff has passed to the front of the queue (they are older requests).
  void promote_due_retries(Clock::time_point now);
  bool idle() const { return queue_.empty() && prefetch_queue_.empty() && backoff_.empty() && loading_ == 0; }
  bool full() const { return done_.size() + loading_ >= finished_cap_; }
  bool settled() const { return idle() || (loading_ == 0 && full()); }

  std::shared_ptr<const VolumeSource> source_;
  BrickLayout layout_;
  mutable std::mutex mutex_;
  std::condition_variable wake_, idle_;
  struct Job {
    std::uint64_t seq;  // the queue's order when queued: collect hands out the lowest first
    BrickId id;
    int attempt = 0;    // reads of this request that failed transiently so far
  };
  struct Retry {
    Clock::time_point due;
    Job job;
  };
  struct Done {
    std::uint64_t seq;
    LoadedBrick brick;
  };
  RetryPolicy retry_;
  std::deque<Job> queue_;
  std::deque<Job> prefetch_queue_;  // started only when queue_ is empty
  std::vector<Retry> backoff_;  // min-heap on `due`: retries waiting out their backoff
  std::uint64_t next_seq_ = 0;
  std::unordered_set<BrickId, BrickIdHash> known_;  // queued, waiting, loading or finished-uncollected
  std::unordered_map<BrickId, std::string, BrickIdHash> failed_;
  std::vector<Done> done_;
  std::vector<BrickFailure> new_failures_;
  std::vector<LoadedBrick> spare_;           // recycled buffers
  std::size_t loading_ = 0;
  std::size_t finished_cap_ = 0;  // finished + loading bricks at most (finished_bytes / brick bytes)
  int bounds_block_ = 0;
  std::uint64_t completed_ = 0;
  LoaderCounts counts_;
  bool stop_ = false;
  std::vector<std::thread> workers_;
};

}  // namespace sl
