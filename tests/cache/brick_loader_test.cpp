#include "cache/brick_loader.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <mutex>
#include <thread>
#include <vector>

#include "cache/synthetic/generate.h"
#include "core/error.h"

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
