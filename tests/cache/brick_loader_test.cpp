#include "cache/brick_loader.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <thread>
#include <unordered_set>
#include <vector>

#include <rapidcheck/gtest.h>

#include "cache/testing/fault_injection.h"
#include "core/scene/generate.h"
#include "core/util/error.h"

namespace sl {
namespace {

std::shared_ptr<MemoryVolumeSource> neurites_source() {
  const GeneratedVolume g = generate_volume("neurites", {50, 40, 30}, 2);
  return std::make_shared<MemoryVolumeSource>(std::make_shared<Volume>(g.intensity),
                                              std::make_shared<Volume>(g.labels), "neurites");
}

std::vector<BrickId> all_bricks(const BrickLayout& l) {
  std::vector<BrickId> ids;
  for (int level = 0; level < l.levels; ++level) {
    const ivec3 n = l.bricks(level);
    for (int z = 0; z < n.z; ++z)
      for (int y = 0; y < n.y; ++y)
        for (int x = 0; x < n.x; ++x) ids.push_back(BrickId::pack(level, {x, y, z}));
  }
  return ids;
}

// A source whose reads wait until the test opens a gate, and which fails some bricks.
class GatedSource final : public VolumeSource {
 public:
  explicit GatedSource(std::shared_ptr<const VolumeSource> inner) : inner_(std::move(inner)) {}
  const VolumeDesc& desc() const override { return inner_->desc(); }
  bool has_labels() const override { return inner_->has_labels(); }
  VoxelType label_type() const override { return inner_->label_type(); }
  const std::string& name() const override { return name_; }
  void read_brick(const BrickLayout& layout, BrickId id, std::span<std::byte> out_intensity,
                  std::span<std::byte> out_labels) const override {
    {
      std::unique_lock lock(mutex_);
      ++entered;
      opened_.wait(lock, [&] { return open_; });
      order.push_back(id);
    }
    ++reads;
    if (id.level() == 0 && id.coord().x == 1) throw InputError(name_, "corrupt chunk");
    inner_->read_brick(layout, id, out_intensity, out_labels);
  }
  void open() {
    {
      std::lock_guard lock(mutex_);
      open_ = true;
    }
    opened_.notify_all();
  }
  mutable std::atomic<int> reads{0};
  mutable std::atomic<int> entered{0};
  mutable std::vector<BrickId> order;  // ids in the order reads passed the gate

 private:
  std::shared_ptr<const VolumeSource> inner_;
  std::string name_ = "store.zarr";
  mutable std::mutex mutex_;
  mutable std::condition_variable opened_;
  bool open_ = false;
};

TEST(BrickLoader, LoadsEveryBrickAsTheSourceReadsIt) {
  const auto src = neurites_source();
  const BrickLayout layout = BrickLayout::make(src->desc(), 16);
  BrickLoader loader(src, layout, 3);
  const std::vector<BrickId> ids = all_bricks(layout);
  EXPECT_EQ(loader.request(ids), ids.size());
  EXPECT_EQ(loader.request(ids), 0u);  // already queued, loading or done: not queued twice
  loader.wait_idle();
  EXPECT_EQ(loader.pending(), ids.size());  // finished, not yet collected
  std::vector<BrickId> got;
  for (;;) {
    LoaderBatch batch = loader.collect(5);  // per-frame budget
    EXPECT_TRUE(batch.failures.empty());
    EXPECT_LE(batch.bricks.size(), 5u);
    if (batch.bricks.empty()) break;
    for (LoadedBrick& b : batch.bricks) {
      std::vector<std::byte> v(b.intensity.size()), l(b.labels.size());
      src->read_brick(layout, b.id, v, l);
      EXPECT_EQ(b.intensity, v) << to_string(b.id);
      EXPECT_EQ(b.labels, l) << to_string(b.id);
      got.push_back(b.id);
      loader.recycle(std::move(b));
    }
  }
  EXPECT_EQ(got, ids);  // oldest request first
  EXPECT_EQ(loader.pending(), 0u);
  EXPECT_EQ(loader.loads_completed(), ids.size());
  // Collected bricks may be requested again (e.g. after eviction).
  EXPECT_EQ(loader.request(std::vector<BrickId>{ids[0]}), 1u);
  loader.wait_idle();
  EXPECT_EQ(loader.collect(10).bricks.size(), 1u);
}

// The buffers of finished bricks waiting for collect() are bounded: the workers stop at the bound and
// go on as bricks are collected; every brick still arrives, intact and in request order, and
// wait_idle() returns at the bound instead of waiting for a collect that only its caller can make.
TEST(BrickLoader, FinishedBricksStayWithinTheirBound) {
  const auto src = neurites_source();
  const BrickLayout layout = BrickLayout::make(src->desc(), 8);
  const std::size_t brick_bytes = layout.stored_voxels() * (1 + voxel_size(src->label_type()));
  BrickLoader loader(src, layout, 2, {}, 5 * brick_bytes);
  EXPECT_EQ(loader.finished_capacity(), 5u);
  const std::vector<BrickId> ids = all_bricks(layout);
  ASSERT_GT(ids.size(), 20u);
  loader.request(ids);
  std::vector<BrickId> got;
  for (int round = 0; got.size() < ids.size(); ++round) {
    ASSERT_LT(round, 1000) << "the loader stopped short of the requests";
    loader.wait_idle();
    EXPECT_EQ(loader.pending(), ids.size() - got.size());  // the rest wait as ids
    LoaderBatch batch = loader.collect(1000);
    EXPECT_LE(batch.bricks.size(), 5u);
    for (LoadedBrick& b : batch.bricks) {
      std::vector<std::byte> v(b.intensity.size()), l(b.labels.size());
      src->read_brick(layout, b.id, v, l);
      EXPECT_EQ(b.intensity, v) << to_string(b.id);
      got.push_back(b.id);
    }
  }
  EXPECT_EQ(got, ids);
  EXPECT_EQ(loader.pending(), 0u);
}

TEST(BrickLoader, CollectNeverWaitsForLoads) {
  const auto gated = std::make_shared<GatedSource>(neurites_source());
  const BrickLayout layout = BrickLayout::make(gated->desc(), 16);
  BrickLoader loader(gated, layout, 2);
  const std::vector<BrickId> ids = all_bricks(layout);
  loader.request(ids);
  while (gated->entered.load() < 2) std::this_thread::yield();
  // Both workers are blocked inside read_brick; collect returns at once with nothing.
  for (int frame = 0; frame < 100; ++frame) {
    const LoaderBatch batch = loader.collect(8);
    EXPECT_TRUE(batch.bricks.empty());
    EXPECT_TRUE(batch.failures.empty());
  }
  EXPECT_EQ(loader.pending(), ids.size());
  EXPECT_EQ(loader.cancel_queued() + 2, ids.size());  // all but the two being read
  gated->open();
  loader.wait_idle();
  EXPECT_EQ(gated->reads.load(), 2);
  EXPECT_EQ(loader.collect(100).bricks.size() + loader.failed_count(), 2u);
}

// Prefetch: a prefetch starts only when no request waits, and requesting a queued
// prefetch promotes it ahead of the other prefetches (and, the latest request, of earlier ones).
TEST(BrickLoader, PrefetchWaitsForRequestsAndARequestPromotesIt) {
  const auto gated = std::make_shared<GatedSource>(neurites_source());
  const BrickLayout layout = BrickLayout::make(gated->desc(), 16);
  BrickLoader loader(gated, layout, 1);
  const BrickId a = BrickId::pack(0, {0, 0, 0}), b = BrickId::pack(0, {0, 1, 0});
  const BrickId p1 = BrickId::pack(0, {2, 0, 0}), p2 = BrickId::pack(0, {0, 0, 1}), p3 = BrickId::pack(0, {2, 1, 0});
  EXPECT_EQ(loader.request(std::vector<BrickId>{a}), 1u);
  while (gated->entered.load() < 1) std::this_thread::yield();  // the one worker holds `a`
  EXPECT_EQ(loader.prefetch(std::vector<BrickId>{p1, p2, p3}), 3u);
  EXPECT_EQ(loader.prefetch(std::vector<BrickId>{p1, a}), 0u);  // known already: not twice
  EXPECT_EQ(loader.request(std::vector<BrickId>{b}), 1u);
  EXPECT_EQ(loader.request(std::vector<BrickId>{p3}), 1u);  // promoted
  EXPECT_EQ(loader.pending(), 5u);
  gated->open();
  loader.wait_idle();
  EXPECT_EQ(gated->order, (std::vector<BrickId>{a, p3, b, p1, p2}));
  EXPECT_EQ(loader.collect(10).bricks.size(), 5u);
  EXPECT_EQ(loader.pending(), 0u);
}

// The latest request orders the queue (the renderer names every brick its last frame missed, nearest
// first): its ids, new or queued before, load first and in its order; queued ids it does not name
// wait behind, in their order, never dropped; collect hands bricks out in the order they loaded.
TEST(BrickLoader, TheLatestRequestLoadsFirstInItsOrder) {
  const auto gated = std::make_shared<GatedSource>(neurites_source());
  const BrickLayout layout = BrickLayout::make(gated->desc(), 16);
  BrickLoader loader(gated, layout, 1);
  const auto id = [](int x, int y, int z) { return BrickId::pack(0, {x, y, z}); };
  const BrickId a = id(0, 0, 0), b = id(0, 1, 0), c = id(2, 0, 0), d = id(0, 0, 1), e = id(2, 1, 0), f = id(0, 1, 1);
  EXPECT_EQ(loader.request(std::vector<BrickId>{a}), 1u);
  while (gated->entered.load() < 1) std::this_thread::yield();  // the one worker holds `a`
  EXPECT_EQ(loader.request(std::vector<BrickId>{b, c, d}), 3u);
  EXPECT_EQ(loader.request(std::vector<BrickId>{e, d, a, c, e}), 1u);  // only e is new
  EXPECT_EQ(loader.prefetch(std::vector<BrickId>{f}), 1u);
  EXPECT_EQ(loader.pending(), 6u);
  gated->open();
  loader.wait_idle();
  EXPECT_EQ(gated->order, (std::vector<BrickId>{a, e, d, c, b, f}));
  std::vector<BrickId> got;
  for (const LoadedBrick& lb : loader.collect(10).bricks) got.push_back(lb.id);
  EXPECT_EQ(got, gated->order);
}

// Given the culling block, coarse bricks arrive with their blocks' bounds (the source's
// read_brick_bounded); level 0 bricks and a loader without a block carry none.
TEST(BrickLoader, CoarseBricksArriveWithTheirBounds) {
  const auto src = neurites_source();
  const BrickLayout layout = BrickLayout::make(src->desc(), 16);
  const std::vector<BrickId> ids = all_bricks(layout);
  for (const int block : {0, 8}) {
    BrickLoader loader(src, layout, 2, {}, BrickLoader::kDefaultFinishedBytes, block);
    loader.request(ids);
    loader.wait_idle();
    std::size_t coarse = 0;
    for (const LoadedBrick& b : loader.collect(ids.size()).bricks) {
      SCOPED_TRACE(to_string(b.id) + ", block " + std::to_string(block));
      if (block == 0 || b.id.level() == 0) {
        EXPECT_TRUE(b.bounds.empty());
        continue;
      }
      const std::vector<ivec3> blocks = brick_culling_blocks(layout, b.id, block);
      std::vector<BlockMetadata> want(blocks.size());
      ASSERT_TRUE(src->bound_blocks(layout, b.id.level(), block, blocks, want));
      ASSERT_EQ(b.bounds.size(), want.size());
      for (std::size_t i = 0; i < want.size(); ++i) {
        EXPECT_EQ(b.bounds[i].min, want[i].min);
        EXPECT_EQ(b.bounds[i].max, want[i].max);
        EXPECT_EQ(b.bounds[i].labels, want[i].labels);
      }
      ++coarse;
    }
    if (block > 0) {
      EXPECT_GT(coarse, 0u);
    }
  }
}

TEST(BrickLoader, FailedBrickReportedOnceAndNeverRetried) {
  const auto gated = std::make_shared<GatedSource>(neurites_source());
  gated->open();
  const BrickLayout layout = BrickLayout::make(gated->desc(), 16);  // level 0: 4 x 3 x 2 bricks
  BrickLoader loader(gated, layout, 2);
  const std::vector<BrickId> ids = all_bricks(layout);
  loader.request(ids);
  loader.wait_idle();
  std::vector<BrickFailure> failures;
  std::size_t loaded = 0;
  for (int frame = 0; frame < 10; ++frame) {
    LoaderBatch batch = loader.collect(4);
    loaded += batch.bricks.size();
    for (const BrickFailure& f : batch.failures) failures.push_back(f);
  }
  // Level-0 bricks with x = 1: one per (y, z), 3 x 2 = 6.
  ASSERT_EQ(failures.size(), 6u);
  EXPECT_EQ(loaded + failures.size(), ids.size());
  for (const BrickFailure& f : failures) {
    EXPECT_EQ(f.id.level(), 0);
    EXPECT_EQ(f.id.coord().x, 1);
    EXPECT_TRUE(loader.failed(f.id));
    EXPECT_EQ(f.reason, "store.zarr: " + to_string(f.id) + ": corrupt chunk");
  }
  EXPECT_EQ(loader.failed_count(), 6u);
  EXPECT_FALSE(loader.failed(BrickId::pack(0, {0, 0, 0})));
  // Requests for failed bricks are ignored: no new reads, no new reports.
  const int reads = gated->reads.load();
  EXPECT_EQ(loader.request(std::vector<BrickId>{failures[0].id, failures[1].id}), 0u);
  loader.wait_idle();
  EXPECT_EQ(gated->reads.load(), reads);
  EXPECT_TRUE(loader.collect(100).failures.empty());
}

// A source whose chosen bricks fail transiently on every read (a store that stays down).
class DownSource final : public VolumeSource {
 public:
  DownSource(std::shared_ptr<const VolumeSource> inner, BrickId down) : inner_(std::move(inner)), down_(down) {}
  const VolumeDesc& desc() const override { return inner_->desc(); }
  bool has_labels() const override { return inner_->has_labels(); }
  VoxelType label_type() const override { return inner_->label_type(); }
  const std::string& name() const override { return name_; }
  void read_brick(const BrickLayout& layout, BrickId id, std::span<std::byte> out_intensity,
                  std::span<std::byte> out_labels) const override {
    if (id == down_) {
      ++down_reads;
      throw TransientError(name_, "HTTP 503");
    }
    inner_->read_brick(layout, id, out_intensity, out_labels);
  }
  mutable std::atomic<int> down_reads{0};

 private:
  std::shared_ptr<const VolumeSource> inner_;
  BrickId down_;
  std::string name_ = "https://example.org/v.zarr";
};

// Waits (tests only) until `done()`; a hang is caught by ctest's timeout.
template <class F>
void wait_until(F done) {
  while (!done()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
}

// Every batch until the loader is idle and everything finished is collected.
LoaderBatch collect_all(BrickLoader& loader) {
  loader.wait_idle();
  LoaderBatch all;
  for (;;) {
    LoaderBatch b = loader.collect(7);
    for (BrickFailure& f : b.failures) all.failures.push_back(std::move(f));
    if (b.bricks.empty()) break;
    for (LoadedBrick& x : b.bricks) all.bricks.push_back(std::move(x));
  }
  return all;
}

RetryPolicy fast_retries(int attempts) {
  RetryPolicy r;
  r.max_attempts = attempts;
  r.first_backoff = std::chrono::milliseconds(1);
  r.max_backoff = std::chrono::milliseconds(4);
  return r;
}

TEST(BrickLoader, BackoffDoublesUpToItsCap) {
  const RetryPolicy r;
  EXPECT_EQ(r.backoff(0).count(), 50);
  EXPECT_EQ(r.backoff(1).count(), 100);
  EXPECT_EQ(r.backoff(3).count(), 400);
  EXPECT_EQ(r.backoff(5).count(), 1000);
  EXPECT_EQ(r.backoff(60).count(), 1000);
}

TEST(BrickLoader, TransientFaultsAreRetriedAndTheBricksArriveIntact) {
  const auto inner = neurites_source();
  const BrickLayout layout = BrickLayout::make(inner->desc(), 16);
  FaultSpec spec;
  spec.transient = 0.5;
  spec.short_read = 0.5;  // every brick fails its first 1..3 reads
  spec.recover = 3;
  const auto src = std::make_shared<FaultInjectingSource>(inner, spec);
  BrickLoader loader(src, layout, 2, fast_retries(4));
  const std::vector<BrickId> ids = all_bricks(layout);
  loader.request(ids);
  const LoaderBatch got = collect_all(loader);
  EXPECT_TRUE(got.failures.empty());
  ASSERT_EQ(got.bricks.size(), ids.size());
  std::uint64_t retries = 0;
  for (const LoadedBrick& b : got.bricks) {
    // Short reads leave garbage behind: a brick is handed out only from a whole read.
    std::vector<std::byte> v(b.intensity.size()), l(b.labels.size());
    inner->read_brick(layout, b.id, v, l);
    EXPECT_EQ(b.intensity, v) << to_string(b.id);
    EXPECT_EQ(b.labels, l) << to_string(b.id);
    const int k = spec.fault(b.id).failing_attempts;
    EXPECT_EQ(src->attempts(b.id), k + 1);
    retries += std::uint64_t(k);
  }
  const LoaderCounts c = loader.counts();
  EXPECT_EQ(c.bricks_retried, ids.size());
  EXPECT_EQ(c.recovered, ids.size());
  EXPECT_EQ(c.retries, retries);
  EXPECT_EQ(c.failed, 0u);
  EXPECT_EQ(loader.pending(), 0u);
}

TEST(BrickLoader, ABrickThatKeepsFailingTransientlyFailsAfterNAttemptsReportedOnce) {
  const BrickId down = BrickId::pack(0, {1, 1, 0});
  const auto src = std::make_shared<DownSource>(neurites_source(), down);
  const BrickLayout layout = BrickLayout::make(src->desc(), 16);
  BrickLoader loader(src, layout, 2, fast_retries(3));
  const std::vector<BrickId> ids = all_bricks(layout);
  loader.request(ids);
  const LoaderBatch got = collect_all(loader);
  EXPECT_EQ(src->down_reads.load(), 3);
  EXPECT_EQ(got.bricks.size(), ids.size() - 1);
  ASSERT_EQ(got.failures.size(), 1u);
  EXPECT_EQ(got.failures[0].id, down);
  EXPECT_EQ(got.failures[0].reason, "https://example.org/v.zarr: " + to_string(down) +
                                        ": HTTP 503 (still failing after 3 attempts)");
  EXPECT_TRUE(loader.failed(down));
  const LoaderCounts c = loader.counts();
  EXPECT_EQ(c.bricks_retried, 1u);
  EXPECT_EQ(c.retries, 2u);
  EXPECT_EQ(c.recovered, 0u);
  EXPECT_EQ(c.failed, 1u);
  // Failed for good: never read or reported again.
  EXPECT_EQ(loader.request(std::vector<BrickId>{down}), 0u);
  EXPECT_TRUE(collect_all(loader).failures.empty());
  EXPECT_EQ(src->down_reads.load(), 3);
}

// Regression: idle workers wait for the earliest retry's due time while another worker pushes a
// retry onto the backoff queue, reallocating it. The wait once held a reference into that queue — a
// use-after-free that ASan caught in a clean-clone CI run. Requests trickle in one at a time and
// every read fails, so the queue grows through each capacity step while three workers wait on it.
TEST(BrickLoader, WorkersWaitingForRetriesSurviveTheBackoffQueueGrowing) {
  const auto inner = neurites_source();
  const BrickLayout layout = BrickLayout::make(inner->desc(), 8);
  FaultSpec spec;
  spec.transient = 1.0;
  spec.recover = 1000;  // k >= 8 for nearly all: they outlast the attempts
  RetryPolicy r;
  r.max_attempts = 8;
  r.first_backoff = std::chrono::milliseconds(1);
  r.max_backoff = std::chrono::milliseconds(2);
  const std::vector<BrickId> all = all_bricks(layout);
  const std::vector<BrickId> ids(all.begin(), all.begin() + std::min<std::ptrdiff_t>(64, std::ptrdiff_t(all.size())));
  ASSERT_EQ(ids.size(), 64u);
  for (int round = 0; round < 4; ++round) {
    const auto src = std::make_shared<FaultInjectingSource>(inner, spec);  // attempts count from 0
    BrickLoader loader(src, layout, 4, r);
    for (const BrickId id : ids) {
      loader.request(std::vector<BrickId>{id});
      std::this_thread::sleep_for(std::chrono::microseconds(100));
    }
    const LoaderBatch got = collect_all(loader);
    std::size_t failed = 0;
    for (const BrickId id : ids) {
      if (spec.fault(id).failing_attempts >= r.max_attempts) ++failed;
    }
    EXPECT_EQ(got.failures.size(), failed);
    EXPECT_EQ(got.bricks.size() + got.failures.size(), ids.size());
    const LoaderCounts c = loader.counts();
    EXPECT_EQ(c.bricks_retried, ids.size());
    EXPECT_EQ(c.failed, failed);
    EXPECT_EQ(c.recovered, ids.size() - failed);
    EXPECT_EQ(loader.pending(), 0u);
  }
}

TEST(BrickLoader, PermanentFaultsAreNotRetried) {
  const auto inner = neurites_source();
  const BrickLayout layout = BrickLayout::make(inner->desc(), 16);
  FaultSpec spec;
  spec.permanent = 1.0;
  const auto src = std::make_shared<FaultInjectingSource>(inner, spec);
  BrickLoader loader(src, layout, 2, fast_retries(5));
  const std::vector<BrickId> ids = all_bricks(layout);
  loader.request(ids);
  const LoaderBatch got = collect_all(loader);
  EXPECT_TRUE(got.bricks.empty());
  ASSERT_EQ(got.failures.size(), ids.size());
  for (const BrickFailure& f : got.failures) {
    EXPECT_EQ(src->attempts(f.id), 1) << to_string(f.id);
    EXPECT_EQ(f.cause, "injected read error in " + to_string(f.id));
  }
  EXPECT_EQ(loader.counts().retries, 0u);
  EXPECT_EQ(loader.counts().bricks_retried, 0u);
  EXPECT_EQ(loader.counts().failed, ids.size());
}

TEST(BrickLoader, ARetryWaitingForItsBackoffBlocksNeitherWorkersNorCollect) {
  const BrickId down = BrickId::pack(0, {0, 0, 0});
  const auto src = std::make_shared<DownSource>(neurites_source(), down);
  const BrickLayout layout = BrickLayout::make(src->desc(), 16);
  RetryPolicy hour;
  hour.first_backoff = hour.max_backoff = std::chrono::hours(1);
  BrickLoader loader(src, layout, 1, hour);  // one worker: were it asleep in the backoff, nothing would load
  const std::vector<BrickId> ids = all_bricks(layout);
  loader.request(ids);  // the failing brick first
  std::size_t loaded = 0;
  while (loaded < ids.size() - 1) {
    const LoaderBatch b = loader.collect(4);
    EXPECT_TRUE(b.failures.empty());
    loaded += b.bricks.size();
    if (b.bricks.empty()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  EXPECT_EQ(src->down_reads.load(), 1);
  EXPECT_EQ(loader.pending(), 1u);  // the retry, waiting
  EXPECT_EQ(loader.counts().retries, 1u);
  EXPECT_TRUE(loader.collect(100).bricks.empty());
  // Cancel drops it: nothing pending, idle at once, and it may be requested afresh.
  EXPECT_EQ(loader.cancel_queued(), 1u);
  EXPECT_EQ(loader.pending(), 0u);
  loader.wait_idle();
  EXPECT_FALSE(loader.failed(down));
  EXPECT_EQ(loader.request(std::vector<BrickId>{down}), 1u);
  wait_until([&] { return src->down_reads.load() == 2; });
  EXPECT_EQ(loader.pending(), 1u);
  // The destructor does not wait an hour for the backoff (ctest's timeout would fail the test).
}

TEST(BrickLoader, InjectedDelaysNeverBlockCollect) {
  const auto inner = neurites_source();
  const BrickLayout layout = BrickLayout::make(inner->desc(), 16);
  FaultSpec spec;
  spec.delay = 1.0;
  spec.delay_ms = 500;
  const auto src = std::make_shared<FaultInjectingSource>(inner, spec);
  BrickLoader loader(src, layout, 1);
  const std::vector<BrickId> ids{BrickId::pack(0, {0, 0, 0}), BrickId::pack(0, {1, 0, 0})};
  loader.request(ids);
  wait_until([&] { return src->attempts(ids[0]) == 1; });  // the worker sleeps in the first read
  // The frame loop goes on meanwhile: these return at once, long before the second's delay.
  for (int frame = 0; frame < 100; ++frame) EXPECT_TRUE(loader.collect(8).bricks.empty());
  EXPECT_EQ(loader.pending(), 2u);
  EXPECT_EQ(collect_all(loader).bricks.size(), 2u);
}

// For any spec and attempt limit, the bricks that finally fail are exactly those the spec fails for
// good or whose transient failures outlast the attempts; every other brick arrives, each failure is
// reported once, and the counts add up.
RC_GTEST_PROP(BrickLoaderProperty, FinalFailuresAreThoseTheSpecSays, ()) {
  static const auto inner = neurites_source();
  const BrickLayout layout = BrickLayout::make(inner->desc(), 16);
  FaultSpec spec;
  // Shares in tenths, summing to at most 1.
  const int p = *rc::gen::inRange(0, 11);
  const int t = *rc::gen::inRange(0, 11 - p);
  const int sh = *rc::gen::inRange(0, 11 - p - t);
  spec.permanent = 0.1 * p;
  spec.transient = 0.1 * t;
  spec.short_read = 0.1 * sh;
  spec.recover = *rc::gen::inRange(1, 6);
  spec.seed = *rc::gen::arbitrary<std::uint64_t>();
  const int attempts = *rc::gen::inRange(1, 5);
  RetryPolicy retry;
  retry.max_attempts = attempts;
  retry.first_backoff = retry.max_backoff = std::chrono::milliseconds(0);
  const auto src = std::make_shared<FaultInjectingSource>(inner, spec);
  BrickLoader loader(src, layout, 2, retry);
  const std::vector<BrickId> ids = all_bricks(layout);
  loader.request(ids);
  const LoaderBatch got = collect_all(loader);

  std::unordered_set<BrickId, BrickIdHash> failed;
  for (const BrickFailure& f : got.failures) RC_ASSERT(failed.insert(f.id).second);  // once each
  std::uint64_t retried = 0, retries = 0, recovered = 0;
  for (const BrickId id : ids) {
    const BrickFault f = spec.fault(id);
    const bool flaky = f.kind == FaultKind::Transient || f.kind == FaultKind::ShortRead;
    const bool fails = f.kind == FaultKind::Permanent || (flaky && f.failing_attempts >= attempts);
    RC_ASSERT(failed.count(id) == (fails ? 1u : 0u));
    RC_ASSERT(loader.failed(id) == fails);
    if (flaky && attempts > 1) {
      ++retried;
      retries += std::uint64_t(std::min(f.failing_attempts, attempts - 1));
      recovered += fails ? 0u : 1u;
    }
  }
  RC_ASSERT(got.bricks.size() + got.failures.size() == ids.size());
  const LoaderCounts c = loader.counts();
  RC_ASSERT(c.bricks_retried == retried);
  RC_ASSERT(c.retries == retries);
  RC_ASSERT(c.recovered == recovered);
  RC_ASSERT(c.failed == got.failures.size());
}

TEST(BrickLoader, DestructionWithWorkQueuedDoesNotHang) {
  const auto src = neurites_source();
  const BrickLayout layout = BrickLayout::make(src->desc(), 8);
  for (int i = 0; i < 5; ++i) {
    BrickLoader loader(src, layout, 4);
    loader.request(all_bricks(layout));
  }
}

}  // namespace
}  // namespace sl
