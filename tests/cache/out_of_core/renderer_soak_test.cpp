// Issue 14 over many views: a short soak (orbit while the distance swings, so the level of detail
// changes back and forth) never stalls, converges at every view, and keeps page-table and tree
// memory flat once the path has been seen; prefetch on a zoom-in loads ahead within the cache's
// spare room, is used by later views, and never evicts a brick the current view uses.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <condition_variable>
#include <memory>
#include <mutex>

#include "cache/out_of_core/renderer.h"
#include "cache/synthetic/procedural_neurites.h"
#include "core/scene/camera_path.h"
#include "tests/test_util.h"

namespace sl {
namespace {

RenderSettings small_image() {
  RenderSettings s;
  s.width = 64;
  s.height = 48;
  return s;
}

std::shared_ptr<const VolumeSource> neurites() {
  return std::make_shared<ProceduralNeuritesSource>(ivec3(512, 512, 256), 3, "procedural:neurites:512x512x256");
}

struct ViewResult {
  Frame last;
  int frames = 0;
  bool converged = false;
  int stalls = 0;  // frames that began with loads in flight and made none (CacheStats::stall)
  std::uint64_t prefetched = 0, prefetch_hits = 0;
};

// One view until it converges, the loader finishing between frames: a frame that then makes no load
// while its loads were pending is a stall (no room), not a slow source.
ViewResult run_view(OutOfCoreRenderer& r, const OutOfCoreScene& scene, const RenderSettings& s, int max_frames = 60) {
  ViewResult v;
  for (; v.frames < max_frames;) {
    v.last = r.render(scene, s);
    ++v.frames;
    const CacheStats& c = v.last.stats.cache;
    if (c.stall) ++v.stalls;
    v.prefetched += c.prefetched;
    v.prefetch_hits += c.prefetch_hits;
    if (r.converged()) {
      v.converged = true;
      break;
    }
    r.wait_for_loads();
  }
  return v;
}

TEST(OutOfCoreSoak, OrbitZoomNeverStallsConvergesAndKeepsMetadataMemoryFlat) {
  const auto src = neurites();
  const TransferFunction tf = default_transfer_function(0, 255);
  OutOfCoreSettings os;
  os.cache_mb = 6;  // about 150 slots of 34³ bytes: under pressure when the view comes close
  os.retire_frames = 20;
  OutOfCoreRenderer r(src, os, 16);
  const CameraPath path = orbit_zoom_path(src->desc().extent(), 16, 2, 0.3f);
  // Round 1 sees the path (how far the tree grows there depends on the order bricks arrive in);
  // rounds 2 and 3 see it again.
  std::size_t pt_bytes[3] = {0, 0, 0}, tree_bytes[3] = {0, 0, 0};
  int pressured = 0;
  for (int round = 0; round < 3; ++round) {
    for (int v = 0; v < path.frames; ++v) {
      const ViewResult res = run_view(r, OutOfCoreScene{&tf, nullptr, path.at(v)}, small_image());
      ASSERT_TRUE(res.converged) << "round " << round << " view " << v << " after " << res.frames << " frames";
      EXPECT_EQ(res.stalls, 0) << "round " << round << " view " << v;
      const CacheStats& c = res.last.stats.cache;
      EXPECT_EQ(c.completeness, 1.0) << "round " << round << " view " << v;
      pressured += c.lod_coarsened > 0.0 ? 1 : 0;
      pt_bytes[round] = std::max<std::size_t>(pt_bytes[round], c.page_table_bytes);
      tree_bytes[round] = std::max<std::size_t>(tree_bytes[round], res.last.stats.tree_bytes);
      // Page-table memory proportional to what is mapped: at most two 64-word chunks per entry
      // above the directory, plus the growth slack of the pool.
      const PageTable& pt = r.page_table();
      EXPECT_LE(pt.live_chunks(), 2 * pt.mapped_entries());
      EXPECT_EQ(c.page_table_bytes, pt.memory_bytes());
    }
  }
  std::printf("[ soak ] page table %.1f / %.1f / %.1f KB, tree %.1f / %.1f / %.1f KB (max of rounds 1 / 2 / 3); %d "
              "views coarsened\n",
              pt_bytes[0] / 1024.0, pt_bytes[1] / 1024.0, pt_bytes[2] / 1024.0, tree_bytes[0] / 1024.0,
              tree_bytes[1] / 1024.0, tree_bytes[2] / 1024.0, pressured);
  EXPECT_GT(pressured, 0) << "the path should bring the cache under pressure somewhere";
  // Once the path has been seen, the same views again cost no more metadata memory.
  EXPECT_LE(pt_bytes[2], pt_bytes[1] + pt_bytes[1] / 8);
  EXPECT_LE(tree_bytes[2], tree_bytes[1] + tree_bytes[1] / 8);
}

using test::max_abs_diff;

// Bounded metadata (cache/metadata_cache.h): with room for a small part of what the path sees, the
// renderer drops the least recently used blocks, reads a brick again where it needs one back, and
// still converges at every view to the image of a renderer that keeps all metadata — through a
// transfer-function change half way (a re-cull from what is left) as well.
TEST(OutOfCoreSoak, BoundedMetadataConvergesToTheImagesOfUnboundedMetadata) {
  const auto src = neurites();
  const TransferFunction tf = default_transfer_function(0, 255);
  const TransferFunction narrow({{0.0f, vec4(0.0f)}, {120.0f, vec4(1.0f, 0.6f, 0.2f, 0.0f)},
                                 {255.0f, vec4(1.0f, 0.6f, 0.2f, 0.8f)}});
  OutOfCoreSettings os;
  os.cache_mb = 24;
  OutOfCoreRenderer all(src, os, 16);
  os.metadata_blocks = 250;
  OutOfCoreRenderer bounded(src, os, 16);
  const CameraPath path = orbit_zoom_path(src->desc().extent(), 8, 1, 0.3f);
  std::size_t most = 0;
  for (int v = 0; v < path.frames; ++v) {
    const TransferFunction& t = v < path.frames / 2 ? tf : narrow;
    const OutOfCoreScene scene{&t, nullptr, path.at(v)};
    const ViewResult a = run_view(all, scene, small_image());
    const ViewResult b = run_view(bounded, scene, small_image());
    ASSERT_TRUE(a.converged && b.converged) << "view " << v;
    EXPECT_EQ(b.last.stats.cache.completeness, 1.0) << "view " << v;
    EXPECT_LE(max_abs_diff(a.last.image, b.last.image), 1e-5f) << "view " << v;
    EXPECT_EQ(b.last.stats.metadata_blocks, bounded.metadata_blocks());
    most = std::max(most, bounded.metadata_blocks());
  }
  std::printf("[ soak ] metadata: bounded at most %zu blocks (capacity %zu, %llu dropped), unbounded %zu\n", most,
              bounded.metadata_capacity(), (unsigned long long)bounded.metadata_evictions(), all.metadata_blocks());
  EXPECT_GT(bounded.metadata_evictions(), 0u) << "the capacity must bind for the test to mean anything";
  EXPECT_GT(all.metadata_blocks(), bounded.metadata_capacity() + bounded.metadata_capacity() / 4);
  EXPECT_LE(most, 2 * bounded.metadata_capacity());
}

TEST(OutOfCorePrefetch, ZoomInLoadsAheadAndNeverEvictsTheViewsBricks) {
  const auto src = neurites();
  const TransferFunction tf = default_transfer_function(0, 255);
  const CameraPath path = zoom_in_path(src->desc().extent(), 8, 0.25f);
  OutOfCoreSettings os;
  os.cache_mb = 12;
  os.prefetch = true;
  OutOfCoreRenderer on(src, os, 16);
  os.prefetch = false;
  OutOfCoreRenderer off(src, os, 16);
  std::uint64_t prefetched = 0, hits = 0;
  for (int v = 0; v < path.frames; ++v) {
    const Camera cam = path.at(v);
    const Camera next = v > 0 ? extrapolate_camera(path.at(v - 1), cam) : cam;
    const OutOfCoreScene scene{&tf, nullptr, cam, v > 0 ? &next : nullptr};
    const ViewResult a = run_view(on, scene, small_image());
    ASSERT_TRUE(a.converged) << "view " << v;
    EXPECT_EQ(a.stalls, 0) << "view " << v;
    prefetched += a.prefetched;
    hits += a.prefetch_hits;
    // Converged: further frames of the same view, with prefetches landing meanwhile, load nothing
    // the view needs again (nothing it uses was evicted) and keep the image.
    for (int k = 0; k < 4; ++k) {
      on.wait_for_loads();
      const Frame f = on.render(scene, small_image());
      prefetched += f.stats.cache.prefetched;
      hits += f.stats.cache.prefetch_hits;
      EXPECT_EQ(f.stats.cache.loads, 0u) << "view " << v << " extra frame " << k;
      EXPECT_EQ(f.stats.cache.bricks_missing, 0u) << "view " << v << " extra frame " << k;
      EXPECT_TRUE(on.converged()) << "view " << v << " extra frame " << k << " misses " << f.stats.cache.misses
                                  << " prefetched " << f.stats.cache.prefetched << " pending " << f.stats.cache.pending
                                  << " metadata computed " << f.stats.metadata_computed << " occ misses "
                                  << f.stats.occupancy_misses << " evictions " << f.stats.cache.evictions;
      EXPECT_EQ(f.image.rgba, a.last.image.rgba) << "view " << v << " extra frame " << k;
    }
    // The same view without prefetch converges to the same image.
    const ViewResult b = run_view(off, OutOfCoreScene{&tf, nullptr, cam}, small_image());
    ASSERT_TRUE(b.converged) << "view " << v;
    float worst = 0.0f;
    for (std::size_t i = 0; i < a.last.image.rgba.size(); ++i) {
      const vec4 d = glm::abs(a.last.image.rgba[i] - b.last.image.rgba[i]);
      worst = std::max({worst, d.x, d.y, d.z, d.w});
    }
    EXPECT_LE(worst, 1e-4f) << "view " << v;
  }
  std::printf("[ prefetch ] zoom-in: %llu bricks prefetched, %llu of them used\n", (unsigned long long)prefetched,
              (unsigned long long)hits);
  EXPECT_GT(prefetched, 0u);
  EXPECT_GT(hits, 0u);
}

// A source whose reads wait until the test opens its gate (no timing involved).
class GatedSource final : public VolumeSource {
 public:
  explicit GatedSource(std::shared_ptr<const VolumeSource> inner) : inner_(std::move(inner)) {}
  ~GatedSource() override { open(); }
  const VolumeDesc& desc() const override { return inner_->desc(); }
  bool has_labels() const override { return inner_->has_labels(); }
  VoxelType label_type() const override { return inner_->label_type(); }
  const std::string& name() const override { return inner_->name(); }
  void read_brick(const BrickLayout& layout, BrickId id, std::span<std::byte> v, std::span<std::byte> l) const override {
    {
      std::unique_lock lock(mutex_);
      opened_.wait(lock, [&] { return open_; });
    }
    inner_->read_brick(layout, id, v, l);
  }
  bool bound_blocks(const BrickLayout& layout, int level, int block, std::span<const ivec3> blocks,
                    std::span<BlockMetadata> out) const override {
    return inner_->bound_blocks(layout, level, block, blocks, out);
  }
  void open() {
    {
      std::lock_guard lock(mutex_);
      open_ = true;
    }
    opened_.notify_all();
  }

 private:
  std::shared_ptr<const VolumeSource> inner_;
  mutable std::mutex mutex_;
  mutable std::condition_variable opened_;
  bool open_ = false;
};

// The stall counter sees a frame that waits: with the reads held, the frame after the first
// requests begins with them in flight and makes nothing resident; once they land, no stall.
TEST(OutOfCoreSoak, StallCountsAFrameWaitingForItsLoads) {
  const auto src = std::make_shared<GatedSource>(neurites());
  const TransferFunction tf = default_transfer_function(0, 255);
  OutOfCoreSettings os;
  os.cache_mb = 16;
  OutOfCoreRenderer r(src, os, 16);
  const OutOfCoreScene scene{&tf, nullptr, default_camera(src->desc().extent())};
  EXPECT_FALSE(r.render(scene, small_image()).stats.cache.stall);  // reports the first misses
  const Frame first = r.render(scene, small_image());              // requests their bricks
  EXPECT_FALSE(first.stats.cache.stall);  // nothing was in flight when it began
  ASSERT_GT(first.stats.cache.pending, 0u);
  const Frame second = r.render(scene, small_image());  // the reads are held
  EXPECT_TRUE(second.stats.cache.stall);
  EXPECT_EQ(second.stats.cache.loads, 0u);
  src->open();
  r.wait_for_loads();
  const Frame third = r.render(scene, small_image());
  EXPECT_FALSE(third.stats.cache.stall);
  EXPECT_GT(third.stats.cache.loads, 0u);
}

}  // namespace
}  // namespace sl
