// The order of a frame's loads (loads_and_misses.cpp): the bricks the last frame missed are read
// nearest first — the distance from that frame's eye to the brick's box — metadata loads before data
// loads, and a later frame's loads ahead of what an earlier one left queued. One loader thread, so the
// source sees the reads in the loader's order.
#include <gtest/gtest.h>

#include <algorithm>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "cache/out_of_core/renderer.h"
#include "core/scene/generate.h"
#include "tests/test_util.h"

namespace sl {
namespace {

// Records the bricks read, in order.
class RecordingSource final : public VolumeSource {
 public:
  explicit RecordingSource(std::shared_ptr<const VolumeSource> inner) : inner_(std::move(inner)) {}
  const VolumeDesc& desc() const override { return inner_->desc(); }
  bool has_labels() const override { return inner_->has_labels(); }
  VoxelType label_type() const override { return inner_->label_type(); }
  const std::string& name() const override { return inner_->name(); }
  void read_brick(const BrickLayout& layout, BrickId id, std::span<std::byte> out_intensity,
                  std::span<std::byte> out_labels) const override {
    {
      std::lock_guard lock(mutex_);
      reads_.push_back(id);
    }
    inner_->read_brick(layout, id, out_intensity, out_labels);
  }
  bool bound_blocks(const BrickLayout& layout, int level, int block, std::span<const ivec3> blocks,
                    std::span<BlockMetadata> out) const override {
    return inner_->bound_blocks(layout, level, block, blocks, out);
  }
  PyramidKind pyramid() const override { return inner_->pyramid(); }
  std::vector<BrickId> reads() const {
    std::lock_guard lock(mutex_);
    return reads_;
  }

 private:
  std::shared_ptr<const VolumeSource> inner_;
  mutable std::mutex mutex_;
  mutable std::vector<BrickId> reads_;
};

float distance_to(const BrickLayout& layout, BrickId id, vec3 eye) {
  const WorldBox b = layout.brick_box(id);
  return glm::length(glm::clamp(eye, b.lo, b.hi) - eye);
}

TEST(OutOfCoreLoadOrder, EachFramesLoadsAreReadNearestFirst) {
  GeneratedVolume g = generate_volume("neurites", ivec3(96, 80, 64), 4);
  auto recording = std::make_shared<RecordingSource>(std::make_shared<MemoryVolumeSource>(
      std::make_shared<const Volume>(std::move(g.intensity)), std::make_shared<const Volume>(std::move(g.labels)),
      "neurites"));
  const TransferFunction tf = default_transfer_function(0, 255);
  RenderSettings s;
  s.width = 64;
  s.height = 48;
  s.block = 8;
  OutOfCoreSettings os;
  os.brick = 16;
  os.lod = 0;  // every miss at level 0: many loads per frame
  os.loader_threads = 1;
  OutOfCoreRenderer r(recording, os, s.block);
  const vec3 extent = recording->desc().extent();
  // Two views from opposite sides: what is near for one is far for the other.
  std::vector<Camera> cams(2, default_camera(extent));
  cams[1].eye = 2.0f * cams[1].center - cams[1].eye;
  std::size_t ordered_runs = 0, longest = 0;
  for (int frame = 0; frame < 12 && !r.converged(); ++frame) {
    const Camera& cam = cams[std::size_t(frame / 3) % 2];
    const std::size_t before = recording->reads().size();
    r.render(OutOfCoreScene{&tf, nullptr, cam}, s);
    // The loads this frame requested were queued in one call and read by one thread after whatever
    // was in flight: read in order of distance from the eye of the frame before (the one that
    // missed them), metadata loads first, so nearest first within each run of the same kind.
    r.wait_for_loads();
    const std::vector<BrickId> reads = recording->reads();
    if (frame == 0 || reads.size() <= before + 2) continue;
    const vec3 eye = cams[std::size_t((frame - 1) / 3) % 2].eye;
    // reads[before] may be a read that began before the frame's request; the rest are its loads.
    std::size_t descents = 0;
    for (std::size_t i = before + 2; i < reads.size(); ++i) {
      descents += distance_to(r.layout(), reads[i], eye) < distance_to(r.layout(), reads[i - 1], eye) ? 1 : 0;
    }
    // At most one step back: from the last metadata load to the first data load.
    EXPECT_LE(descents, 1u) << "frame " << frame + 1 << ": " << reads.size() - before << " reads";
    ++ordered_runs;
    longest = std::max(longest, reads.size() - before);
  }
  EXPECT_GE(ordered_runs, 1u);
  EXPECT_GE(longest, 20u) << "a frame must request many loads at a time";
}

}  // namespace
}  // namespace sl
