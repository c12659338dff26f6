// The out-of-core frame loop end to end: convergence to the in-core image, lazy metadata, retirement,
// faults, and the memory bound on a virtual 8 TiB volume.
#include <gtest/gtest.h>
#include <sys/resource.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

#include "core/scene/generate.h"
#include "cache/out_of_core/renderer.h"
#include "cache/synthetic/procedural_neurites.h"
#include "core/occupancy/block_metadata.h"
#include "core/frame/in_core_renderer.h"
#include "core/util/error.h"
#include "tests/test_util.h"

namespace sl {
namespace {

struct Data {
  std::shared_ptr<const Volume> volume, labels;
  std::uint32_t label_count = 0;
};

Data neurites(ivec3 dims, std::uint32_t seed) {
  GeneratedVolume g = generate_volume("neurites", dims, seed);
  Data d;
  d.label_count = g.label_count;
  d.volume = std::make_shared<const Volume>(std::move(g.intensity));
  d.labels = std::make_shared<const Volume>(std::move(g.labels));
  return d;
}

Frame converge(OutOfCoreRenderer& r, const OutOfCoreScene& scene, const RenderSettings& s, int max_frames = 60) {
  Frame f;
  for (int i = 0; i < max_frames; ++i) {
    f = r.render(scene, s);
    if (r.converged()) return f;
    r.wait_for_loads();  // tests: let the loader finish so convergence is reached in few frames
  }
  ADD_FAILURE() << "did not converge in " << max_frames << " frames";
  return f;
}

using test::max_abs_diff;

TEST(OutOfCore, ConvergedImageEqualsInCoreWithAQuarterCache) {
  const Data d = neurites(ivec3(128, 128, 128), 5);
  const TransferFunction tf = default_transfer_function(0, 255);
  const LabelSet enabled = parse_enable_spec("fraction:0.1:1", d.label_count);
  const Camera cam = default_camera(d.volume->desc().extent());
  RenderSettings s;
  s.width = 96;
  s.height = 80;
  // In core.
  Scene scene{d.volume.get(), d.labels.get(), &tf, &enabled, cam};
  const Frame in_core = InCoreRenderer().render(scene, s);
  // Out of core, level 0 pinned, cache of a quarter of the volume (intensity + labels).
  OutOfCoreSettings os;
  os.brick = 16;
  os.lod = 0;
  const double volume_mb = double(d.volume->desc().byte_size() + d.labels->desc().byte_size()) / (1 << 20);
  os.cache_mb = std::size_t(std::ceil(0.25 * volume_mb));
  auto source = std::make_shared<MemoryVolumeSource>(d.volume, d.labels, "neurites");
  OutOfCoreRenderer r(source, os, 16);
  const Frame ooc = converge(r, OutOfCoreScene{&tf, &enabled, cam}, s);
  EXPECT_LE(max_abs_diff(ooc.image, in_core.image), 1e-5f);
  EXPECT_LE(ooc.stats.cache.resident_mb, double(os.cache_mb));
  EXPECT_GT(ooc.stats.cache.hits, 0u);
  float alpha = 0;
  for (const vec4& c : in_core.image.rgba) alpha += c.w;
  EXPECT_GT(alpha, 1.0f) << "the comparison must not be of two empty images";
}

TEST(OutOfCore, ConvergedImageEqualsInCoreForIsoAndFullCache) {
  const Data d = neurites(ivec3(72, 64, 56), 2);
  const TransferFunction tf = default_transfer_function(0, 255);
  const Camera cam = default_camera(d.volume->desc().extent());
  RenderSettings s;
  s.width = 64;
  s.height = 48;
  s.mode = RenderMode::Iso;
  s.iso = 140.0f;
  Scene scene{d.volume.get(), d.labels.get(), &tf, nullptr, cam};
  const Frame in_core = InCoreRenderer().render(scene, s);
  OutOfCoreSettings os;
  os.brick = 32;
  os.lod = 0;
  os.cache_mb = 64;
  OutOfCoreRenderer r(std::make_shared<MemoryVolumeSource>(d.volume, d.labels, "n"), os, 16);
  const Frame ooc = converge(r, OutOfCoreScene{&tf, nullptr, cam}, s);
  EXPECT_LE(max_abs_diff(ooc.image, in_core.image), 1e-5f);
}

TEST(OutOfCore, RegionsTheCameraNeverSeesGetNoMetadata) {
  const Data d = neurites(ivec3(128, 64, 64), 3);
  const TransferFunction tf = default_transfer_function(0, 255);
  // Orthographic view of the left half only (x < 64), looking down z.
  Camera cam;
  cam.projection = Projection::Orthographic;
  cam.center = vec3(32, 32, 32);
  cam.eye = vec3(32, 32, 200);
  cam.height = 60.0f;  // covers x in [2, 62] at a square aspect
  RenderSettings s;
  s.width = s.height = 48;
  OutOfCoreSettings os;
  os.brick = 16;
  os.lod = 0;
  os.cache_mb = 64;
  OutOfCoreRenderer r(std::make_shared<MemoryVolumeSource>(d.volume, d.labels, "n"), os, 16);
  converge(r, OutOfCoreScene{&tf, nullptr, cam}, s);
  EXPECT_GT(r.metadata_blocks_in(Box3{vec3(0, 0, 0), vec3(64, 64, 64)}), 0u);
  EXPECT_EQ(r.metadata_blocks_in(Box3{vec3(80, 0, 0), vec3(128, 64, 64)}), 0u);
}

TEST(OutOfCore, TreeAndCacheFallBackAfterTheCameraMovesAway) {
  const Data d = neurites(ivec3(128, 128, 128), 9);
  const TransferFunction tf = default_transfer_function(0, 255);
  RenderSettings s;
  s.width = s.height = 48;
  s.block = 8;
  OutOfCoreSettings os;
  os.brick = 16;
  os.lod = 0;
  os.cache_mb = 4;
  os.retire_frames = 3;
  OutOfCoreRenderer r(std::make_shared<MemoryVolumeSource>(d.volume, d.labels, "n"), os, 8);
  // Close-up inside one corner: fine tree there.
  Camera near;
  near.eye = vec3(20, 20, 60);
  near.center = vec3(20, 20, 0);
  near.fov_deg = 40.0f;
  converge(r, OutOfCoreScene{&tf, nullptr, near}, s);
  const std::size_t nodes_near = r.tree().node_count();
  // Move to look at a thin slab at the other corner, orthographically; the corner's nodes go unused.
  Camera away;
  away.projection = Projection::Orthographic;
  away.eye = vec3(120, 120, 300);
  away.center = vec3(120, 120, 0);
  away.height = 8.0f;
  Frame f;
  for (int i = 0; i < 12; ++i) {
    f = r.render(OutOfCoreScene{&tf, nullptr, away}, s);
    r.wait_for_loads();
  }
  EXPECT_LT(r.tree().node_count(), nodes_near) << "unused nodes must be retired";
  EXPECT_LE(f.stats.cache.resident_mb, double(os.cache_mb));
}

// DESIGN.md "Occupancy histogram tree": a transfer-function or label change re-culls the tree from the cached metadata
// (OccupancyTree::recull); nothing is reloaded and no metadata is computed again, and the view
// converges to the in-core image under the new culling.
TEST(OutOfCore, TransferFunctionAndLabelChangesReCullWithoutLoadsOrNewMetadata) {
  const Data d = neurites(ivec3(96, 80, 64), 6);
  const TransferFunction wide = default_transfer_function(0, 255);
  // A narrow opaque band: most blocks that were NON_EMPTY become EMPTY, and the reverse is tested by
  // going back.
  const TransferFunction narrow({{0, {0, 0, 0, 0}}, {180, {0, 0, 0, 0}}, {200, {0.2f, 0.7f, 1, 0.6f}}, {220, {0, 0, 0, 0}}});
  const LabelSet some = parse_enable_spec("fraction:0.2:1", d.label_count);
  const Camera cam = default_camera(d.volume->desc().extent());
  RenderSettings s;
  s.width = 64;
  s.height = 48;
  OutOfCoreSettings os;
  os.brick = 16;
  os.lod = 0;
  os.cache_mb = 64;  // the whole volume stays resident
  OutOfCoreRenderer r(std::make_shared<MemoryVolumeSource>(d.volume, d.labels, "n"), os, 16);
  // First view: each culling block's metadata is computed once, and counted by the process-wide
  // counter exactly as in core.
  std::uint64_t computed = block_metadata_computations();
  std::uint64_t counted = 0;
  Frame first;
  for (int i = 0; i < 60 && !r.converged(); ++i) {
    first = r.render(OutOfCoreScene{&wide, nullptr, cam}, s);
    counted += first.stats.metadata_computed;
    r.wait_for_loads();
  }
  ASSERT_TRUE(r.converged());
  const std::size_t blocks = r.metadata_blocks();
  EXPECT_GT(blocks, 0u);
  EXPECT_EQ(counted, blocks);
  EXPECT_EQ(block_metadata_computations() - computed, counted);
  computed = block_metadata_computations();

  struct Change {
    const TransferFunction* tf;
    const LabelSet* enabled;
  };
  std::uint64_t samples = first.stats.samples;
  for (const Change c : {Change{&narrow, nullptr}, Change{&narrow, &some}, Change{&wide, &some}}) {
    const OutOfCoreScene scene{c.tf, c.enabled, cam};
    Frame f;
    for (int i = 0; i < 30 && !(i > 0 && r.converged()); ++i) {
      f = r.render(scene, s);
      EXPECT_EQ(f.stats.cache.loads, 0u) << "frame " << i;
      EXPECT_EQ(f.stats.metadata_computed, 0u) << "frame " << i;
      r.wait_for_loads();
    }
    EXPECT_TRUE(r.converged());
    EXPECT_EQ(block_metadata_computations(), computed);
    EXPECT_EQ(r.metadata_blocks(), blocks);
    EXPECT_NE(f.stats.samples, samples) << "the re-cull took effect";
    samples = f.stats.samples;
    const Frame in_core = InCoreRenderer().render(Scene{d.volume.get(), d.labels.get(), c.tf, c.enabled, cam}, s);
    EXPECT_LE(max_abs_diff(f.image, in_core.image), 1e-5f);
    computed = block_metadata_computations();  // (the in-core reference computed its own)
  }
}

// A source whose bricks at one level fail, several bricks per corrupt "chunk" (bricks (1, y, z) lie
// in chunk (y / 2, z / 2)): each chunk reported once, rendered as missing, rendering goes on.
class FailingSource final : public VolumeSource {
 public:
  explicit FailingSource(std::shared_ptr<MemoryVolumeSource> inner) : inner_(std::move(inner)) {}
  const VolumeDesc& desc() const override { return inner_->desc(); }
  bool has_labels() const override { return inner_->has_labels(); }
  VoxelType label_type() const override { return inner_->label_type(); }
  const std::string& name() const override { return name_; }
  void read_brick(const BrickLayout& layout, BrickId id, std::span<std::byte> a,
                  std::span<std::byte> b) const override {
    if (id.level() == 0 && id.coord().x == 1) {
      throw InputError(name_, "chunk " + chunk(id.coord().y / 2, id.coord().z / 2) + ": checksum mismatch (simulated)");
    }
    inner_->read_brick(layout, id, a, b);
  }

  static std::string chunk(int y, int z) { return "'0/" + std::to_string(z) + "/" + std::to_string(y) + "/0'"; }

 private:
  std::shared_ptr<MemoryVolumeSource> inner_;
  std::string name_ = "broken.zarr";
};

TEST(OutOfCore, FailedBricksAreReportedOnceAndRenderedAsMissing) {
  const Data d = neurites(ivec3(64, 64, 64), 4);
  const TransferFunction tf = default_transfer_function(0, 255);
  RenderSettings s;
  s.width = s.height = 40;
  OutOfCoreSettings os;
  os.brick = 16;
  os.lod = 0;
  os.cache_mb = 32;
  auto src = std::make_shared<FailingSource>(std::make_shared<MemoryVolumeSource>(d.volume, d.labels, "n"));
  OutOfCoreRenderer r(src, os, 16);
  testing::internal::CaptureStderr();
  const Frame f = converge(r, OutOfCoreScene{&tf, nullptr, default_camera(d.volume->desc().extent())}, s);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_GT(r.failed_bricks(), 0u);
  // Each failing chunk appears exactly once, however many bricks it covers.
  const auto count = [&err](const std::string& needle) {
    std::size_t n = 0;
    for (std::size_t pos = 0; (pos = err.find(needle, pos)) != std::string::npos; ++pos) ++n;
    return n;
  };
  std::size_t chunks = 0;
  for (int y = 0; y < 2; ++y) {
    for (int z = 0; z < 2; ++z) {
      const std::size_t n = count(FailingSource::chunk(y, z));
      EXPECT_LE(n, 1u) << err;
      chunks += n;
    }
  }
  EXPECT_GT(chunks, 0u);
  EXPECT_EQ(count("broken.zarr"), chunks) << err;
  EXPECT_LT(chunks, r.failed_bricks()) << "bricks sharing a chunk must share one warning";
  EXPECT_NE(err.find("level 0 brick"), std::string::npos) << err;
  EXPECT_EQ(f.stats.cache.failed, r.failed_bricks());
}

TEST(OutOfCore, CacheTooSmallIsAClearErrorUpFront) {
  const Data d = neurites(ivec3(256, 256, 256), 1);
  OutOfCoreSettings os;
  os.brick = 64;
  os.cache_mb = 1;
  try {
    OutOfCoreRenderer r(std::make_shared<MemoryVolumeSource>(d.volume, d.labels, "n"), os, 16);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("--cache-mb"), std::string::npos) << e.what();
  }
}

TEST(OutOfCore, Procedural8TiBRendersInBoundedMemory) {
  // Run as a child process so its peak RSS is its own.
  const auto dir = test::scratch_dir();
  const test::RunResult r = test::run_sparseleap(
      "render --volume procedural:neurites:32768x32768x8192 --cache-mb 512 --frames 6 --size 128x128 --out " +
      (dir / "big").string() + " --stats-json " + (dir / "big.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  rusage ru{};
  getrusage(RUSAGE_CHILDREN, &ru);
  EXPECT_LT(ru.ru_maxrss, 2L * 1024 * 1024) << "peak RSS in KiB";  // < 2 GiB
  const std::string stats = test::read_text(dir / "big.json");
  EXPECT_NE(stats.find("\"page_table_bytes\""), std::string::npos);
  EXPECT_NE(stats.find("\"tree_bytes\""), std::string::npos);
  EXPECT_NE(stats.find("\"resident_mb\""), std::string::npos);
}

// OutOfCoreSettings::upload_budget bounds the bricks a frame makes resident; without a bound (what
// `render` runs with) a frame takes every brick the loader has finished. Either way the frames
// converge to the same image.
TEST(OutOfCore, UploadBudgetBoundsEachFramesLoadsAndUnboundedTakesAllFinished) {
  const Data d = neurites(ivec3(96, 96, 96), 4);
  const TransferFunction tf = default_transfer_function(0, 255);
  const Camera cam = default_camera(d.volume->desc().extent());
  RenderSettings s;
  s.width = s.height = 48;
  s.block = 8;
  const auto source = std::make_shared<MemoryVolumeSource>(d.volume, d.labels, "n");
  Frame last[2];
  std::uint64_t most_loads[2] = {0, 0};
  for (const int unbounded : {0, 1}) {
    OutOfCoreSettings os;
    os.brick = 8;  // 1,728 level-0 bricks
    os.lod = 0;
    os.cache_mb = 64;
    os.upload_budget = unbounded ? std::numeric_limits<std::size_t>::max() : 40;
    OutOfCoreRenderer r(source, os, 8);
    for (int i = 0; i < 400 && !r.converged(); ++i) {
      last[unbounded] = r.render(OutOfCoreScene{&tf, nullptr, cam}, s);
      most_loads[unbounded] = std::max(most_loads[unbounded], last[unbounded].stats.cache.loads);
      r.wait_for_loads();
    }
    ASSERT_TRUE(r.converged()) << unbounded;
  }
  EXPECT_EQ(most_loads[0], 40u);
  EXPECT_GT(most_loads[1], 400u) << "a frame after the loader finished takes what it finished";
  EXPECT_EQ(last[0].image.rgba, last[1].image.rgba);
  EXPECT_LT(last[1].stats.cache.frame, last[0].stats.cache.frame);
}

// A source given without its labels (what the commands give a renderer that shows none) fills slots
// of intensity and mask only: more bricks in the same budget, the same DVR frame.
TEST(OutOfCore, SourceWithoutLabelsHoldsMoreBricksAndRendersTheSameFrame) {
  const Data d = neurites(ivec3(96, 80, 64), 6);
  const TransferFunction tf = default_transfer_function(0, 255);
  const Camera cam = default_camera(d.volume->desc().extent());
  RenderSettings s;
  s.width = s.height = 48;
  OutOfCoreSettings os;
  os.brick = 16;
  os.lod = 0;
  os.cache_mb = 16;
  const auto source = std::make_shared<MemoryVolumeSource>(d.volume, d.labels, "n");
  OutOfCoreRenderer with(source, os, 16), without(without_labels(source), os, 16);
  const Frame a = converge(with, OutOfCoreScene{&tf, nullptr, cam}, s);
  const Frame b = converge(without, OutOfCoreScene{&tf, nullptr, cam}, s);
  EXPECT_EQ(a.image.rgba, b.image.rgba);
  const std::uint64_t label_bytes = 18 * 18 * 18 * std::uint64_t(voxel_size(d.labels->type()));
  EXPECT_EQ(a.stats.cache.slot_bytes - b.stats.cache.slot_bytes, (label_bytes + 63) / 64 * 64);  // rows of 64 bytes
  EXPECT_GT(b.stats.cache.slots, a.stats.cache.slots);
  EXPECT_LE(double(b.stats.cache.slots * b.stats.cache.slot_bytes), double(os.cache_mb) * (1 << 20));
}

}  // namespace
}  // namespace sl
