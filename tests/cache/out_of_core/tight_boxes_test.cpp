// Tight boxes out of core (cache/out_of_core/tight_boxes.h): the SparseLeap lists from NON_EMPTY leaf
// boxes shrunk to the set cells of their resident bricks' voxel masks give the converged frame of
// whole boxes — the same image and the same samples taken — at any level of detail, transfer
// function, mode and brick size; the shrunk extents outlive their bricks; and a box is shrunk only
// where all its samples take one level.
#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include <cmath>
#include <memory>
#include <string>

#include "cache/out_of_core/renderer.h"
#include "cache/out_of_core/tight_boxes.h"
#include "core/scene/generate.h"
#include "core/scene/labels.h"
#include "tests/test_util.h"

namespace sl {
namespace {

struct Data {
  std::shared_ptr<const Volume> volume, labels;
  std::uint32_t label_count = 0;
};

const Data& neurites() {
  static const Data d = [] {
    GeneratedVolume g = generate_volume("neurites", ivec3(96, 80, 72), 5);
    Data r;
    r.label_count = g.label_count;
    r.volume = std::make_shared<const Volume>(std::move(g.intensity));
    r.labels = std::make_shared<const Volume>(std::move(g.labels));
    return r;
  }();
  return d;
}

Camera close_camera(const vec3& extent, float zoom) {
  Camera c = default_camera(extent);
  c.eye = c.center + (c.eye - c.center) * zoom;
  return c;
}

// Renders until converged; the frames' evictions are added to `evictions`.
Frame converge(OutOfCoreRenderer& r, const OutOfCoreScene& scene, const RenderSettings& s, int max_frames = 60,
               std::uint64_t* evictions = nullptr) {
  Frame f;
  for (int i = 0; i < max_frames; ++i) {
    f = r.render(scene, s);
    if (evictions) *evictions += f.stats.cache.evictions;
    if (r.converged()) return f;
    r.wait_for_loads();
  }
  ADD_FAILURE() << "did not converge in " << max_frames << " frames";
  return f;
}

struct Pair {
  Frame tight, whole;
  std::size_t shrunk = 0, kept = 0;
};

// The converged frames of the same view with and without tight boxes.
Pair converge_both(const OutOfCoreSettings& os, const RenderSettings& s, const OutOfCoreScene& scene,
                   PyramidKind pyramid) {
  const Data& d = neurites();
  auto source = std::make_shared<MemoryVolumeSource>(d.volume, d.labels, "neurites", pyramid);
  OutOfCoreRenderer tight(source, os, s.block), whole(source, os, s.block);
  RenderSettings off = s;
  off.tight_boxes = false;
  Pair p;
  p.tight = converge(tight, scene, s);
  p.whole = converge(whole, scene, off);
  p.shrunk = tight.tight_boxes_shrunk();
  p.kept = tight.tight_boxes_kept();
  EXPECT_EQ(whole.tight_boxes_shrunk(), 0u);
  return p;
}

TEST(TightBoxesOutOfCore, ConvergedFrameEqualsWholeBoxesWhereLevelsVary) {
  const Data& d = neurites();
  const TransferFunction tf = default_transfer_function(0, 255);
  RenderSettings s;
  s.width = 96;
  s.height = 72;
  s.block = 8;
  OutOfCoreSettings os;
  os.brick = 16;
  os.cache_mb = 64;  // the whole volume: no pressure
  os.lod_bias = 4.0f;  // a close view whose far half takes coarser levels
  const OutOfCoreScene scene{&tf, nullptr, close_camera(d.volume->desc().extent(), 0.4f)};
  const Pair p = converge_both(os, s, scene, PyramidKind::Max);
  EXPECT_EQ(test::max_abs_diff(p.tight.image, p.whole.image), 0.0f);
  EXPECT_EQ(p.tight.stats.samples, p.whole.stats.samples);
  EXPECT_EQ(p.tight.stats.useful_samples, p.whole.stats.useful_samples);
  EXPECT_EQ(p.tight.stats.cache.completeness, 1.0);
  EXPECT_GT(p.shrunk, 0u) << "the view must shrink boxes";
  EXPECT_GT(p.kept, 0u) << "the view must have boxes whose samples straddle two levels";
  EXPECT_GT(p.whole.stats.cache.samples_left_out, p.tight.stats.cache.samples_left_out)
      << "the tight lists must pass over fewer clear samples";
  EXPECT_GT(p.tight.stats.useful_samples, 1000u);
}

RC_GTEST_PROP(TightBoxesOutOfCore, ConvergedFrameEqualsWholeBoxesForAnyWindowModeBrickOrLevel, ()) {
  const Data& d = neurites();
  const int lo = *rc::gen::inRange(0, 250);
  const int hi = *rc::gen::inRange(lo + 1, 256);
  const TransferFunction tf({TfPoint{float(lo), vec4(0.2f, 0.6f, 1.0f, 0.0f)},
                             TfPoint{float(hi), vec4(1.0f, 0.8f, 0.3f, *rc::gen::element(0.05f, 0.5f, 1.0f))}});
  const LabelSet enabled =
      parse_enable_spec("fraction:0.5:" + std::to_string(*rc::gen::inRange(1, 9)), d.label_count);
  RenderSettings s;
  s.width = 40;
  s.height = 32;
  s.block = 8;
  s.mode = *rc::gen::element(RenderMode::Dvr, RenderMode::Labels);
  s.ert = *rc::gen::arbitrary<bool>();
  s.simd = *rc::gen::arbitrary<bool>();
  OutOfCoreSettings os;
  os.brick = *rc::gen::element(8, 16);
  os.lod = *rc::gen::element(-1, -1, 0, 1);
  os.lod_bias = *rc::gen::element(1.0f, 2.0f, 4.0f);
  os.cache_mb = 64;
  const bool label_mask = s.mode == RenderMode::Labels || *rc::gen::arbitrary<bool>();
  const float zoom = *rc::gen::element(1.0f, 0.6f, 0.3f);
  const OutOfCoreScene scene{&tf, label_mask ? &enabled : nullptr, close_camera(d.volume->desc().extent(), zoom)};
  const Pair p = converge_both(os, s, scene, *rc::gen::element(PyramidKind::Mean, PyramidKind::Max));
  RC_ASSERT(test::max_abs_diff(p.tight.image, p.whole.image) == 0.0f);
  RC_ASSERT(p.tight.stats.samples == p.whole.stats.samples);
  RC_ASSERT(p.tight.stats.useful_samples == p.whole.stats.useful_samples);
}

// An extent is remembered: after the view's bricks were evicted, its boxes are shrunk on the first
// frame back, before anything is loaded again, and the view converges to the same image.
TEST(TightBoxesOutOfCore, ExtentsOutliveTheirBricks) {
  const Data& d = neurites();
  const TransferFunction tf = default_transfer_function(0, 255);
  RenderSettings s;
  s.width = 64;
  s.height = 48;
  s.block = 8;
  OutOfCoreSettings os;
  os.brick = 16;
  os.lod = 0;
  os.cache_mb = 1;  // less than the volume's bricks
  auto source = std::make_shared<MemoryVolumeSource>(d.volume, d.labels, "neurites", PyramidKind::Max);
  OutOfCoreRenderer r(source, os, s.block);
  const vec3 extent = d.volume->desc().extent();
  Camera near_corner = close_camera(extent, 0.5f);
  Camera far_corner = near_corner;
  far_corner.eye = 2.0f * far_corner.center - near_corner.eye;
  const OutOfCoreScene here{&tf, nullptr, near_corner}, there{&tf, nullptr, far_corner};
  // Both views once, so that the tree has grown where either looks.
  converge(r, there, s);
  const Frame first = converge(r, here, s);
  // The geometry is the whole tree's: boxes whose bricks are not resident (elsewhere) stay whole.
  const std::size_t shrunk = r.tight_boxes_shrunk(), kept = r.tight_boxes_kept();
  ASSERT_GT(shrunk, 0u);
  std::uint64_t evictions = 0;
  converge(r, there, s, 60, &evictions);
  ASSERT_GT(evictions, 0u) << "the other view must evict bricks";
  const Frame back = r.render(here, s);
  EXPECT_LT(back.stats.cache.completeness, 1.0) << "bricks of this view must have been evicted";
  // Every box shrunk before is shrunk still, its bricks resident or not.
  EXPECT_GE(r.tight_boxes_shrunk(), shrunk);
  EXPECT_LE(r.tight_boxes_kept(), kept);
  r.wait_for_loads();
  const Frame again = converge(r, here, s);
  EXPECT_EQ(test::max_abs_diff(again.image, first.image), 0.0f);
  EXPECT_EQ(again.stats.samples, first.stats.samples);
}

// box_level: where it names a level, every point of the box takes it.
RC_GTEST_PROP(TightBoxesOutOfCore, BoxLevelIsTheLevelOfEveryPointInTheBox, ()) {
  LodParams lod;
  lod.levels = *rc::gen::inRange(2, 8);
  lod.pixel_angle = float(*rc::gen::inRange(1, 200)) * 1e-4f;
  lod.inv_voxel = float(*rc::gen::inRange(1, 40)) * 0.1f;
  RayGenerator gen;
  gen.eye = vec3(*rc::gen::inRange(-300, 300), *rc::gen::inRange(-300, 300), *rc::gen::inRange(-300, 300));
  const vec3 lo(*rc::gen::inRange(0, 400), *rc::gen::inRange(0, 400), *rc::gen::inRange(0, 400));
  const vec3 size(*rc::gen::inRange(1, 64), *rc::gen::inRange(1, 64), *rc::gen::inRange(1, 64));
  const Box3 box{lo, lo + size};
  const int level = TightBoxes::box_level(box, lod, gen);
  RC_PRE(level >= 0);
  for (int i = 0; i < 64; ++i) {
    const vec3 f(*rc::gen::inRange(0, 1001), *rc::gen::inRange(0, 1001), *rc::gen::inRange(0, 1001));
    const vec3 p = box.lo + f * 1e-3f * size;
    RC_ASSERT(lod.level_at(glm::length(p - gen.eye)) == level);
  }
}

}  // namespace
}  // namespace sl
