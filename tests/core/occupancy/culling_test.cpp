// Culling (paper §5.2): dvr, iso, labels, mip, and the property that makes EMPTY conservative: no
// sample the caster takes inside an EMPTY block can contribute (core/recon/sampling.h's sample model).
#include "core/occupancy/culling.h"

#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include <vector>

#include "core/recon/sampling.h"
#include "core/scene/volume.h"

namespace sl {
namespace {

using C = OccupancyClass;

BlockMetadata meta(float lo, float hi, std::vector<std::uint32_t> labels = {}, bool has_labels = false) {
  BlockMetadata m;
  m.min = lo;
  m.max = hi;
  m.labels = std::move(labels);
  m.has_labels = has_labels;
  m.computed = true;
  return m;
}

const TransferFunction& ramp_tf() {  // transparent below 100
  static const TransferFunction tf({{0.0f, vec4(0.0f)}, {100.0f, vec4(0.0f)}, {200.0f, vec4(1.0f)}});
  return tf;
}

TEST(Culling, DvrUsesTheMaximumOpacityOverTheRange) {
  CullParams p;
  p.tf = &ramp_tf();
  EXPECT_EQ(classify_block(meta(0.0f, 90.0f), p), C::Empty);
  EXPECT_EQ(classify_block(meta(0.0f, 120.0f), p), C::NonEmpty);
  EXPECT_EQ(classify_block(meta(150.0f, 160.0f), p), C::NonEmpty);
  p.mode = RenderMode::Mip;  // MIP: never empty by value
  EXPECT_EQ(classify_block(meta(0.0f, 90.0f), p), C::NonEmpty);
}

TEST(Culling, IsoIsEmptyOutsideTheRange) {
  CullParams p;
  p.mode = RenderMode::Iso;
  p.iso = 50.0f;
  EXPECT_EQ(classify_block(meta(0.0f, 49.0f), p), C::Empty);
  EXPECT_EQ(classify_block(meta(51.0f, 90.0f), p), C::Empty);
  EXPECT_EQ(classify_block(meta(50.0f, 90.0f), p), C::NonEmpty);
  EXPECT_EQ(classify_block(meta(0.0f, 50.0f), p), C::NonEmpty);
}

TEST(Culling, LabelsAreEmptyWhenNoEnabledLabelIsPresent) {
  LabelSet enabled(20);
  enabled.enable(3);
  enabled.enable(11);
  CullParams p;
  p.mode = RenderMode::Labels;
  p.tf = &ramp_tf();
  p.enabled = &enabled;
  EXPECT_EQ(classify_block(meta(150.0f, 200.0f, {0, 4, 12}, true), p), C::Empty);
  EXPECT_EQ(classify_block(meta(150.0f, 200.0f, {0}, true), p), C::Empty);  // background only
  EXPECT_EQ(classify_block(meta(150.0f, 200.0f, {0, 11}, true), p), C::NonEmpty);
  EXPECT_EQ(classify_block(meta(0.0f, 90.0f, {0, 11}, true), p), C::Empty);  // transparent anyway
  p.mode = RenderMode::Mip;  // the label test applies in every mode
  EXPECT_EQ(classify_block(meta(0.0f, 90.0f, {4}, true), p), C::Empty);
  EXPECT_EQ(classify_block(meta(0.0f, 90.0f, {3}, true), p), C::NonEmpty);
  EXPECT_EQ(classify_block(meta(0.0f, 90.0f, {}, false), p), C::NonEmpty);  // no label volume
}

TEST(Culling, MissingMetadataIsUnknown) {
  CullParams p;
  p.tf = &ramp_tf();
  EXPECT_EQ(classify_block(BlockMetadata{}, p), C::Unknown);
}

// A random u8 volume and label volume, random TF with transparent ranges, random enabled labels.
RC_GTEST_PROP(CullingProperty, NoSampleInAnEmptyBlockContributes, (std::uint64_t seed)) {
  std::uint64_t s = seed;
  auto next = [&] {
    s = s * 6364136223846793005ull + 1442695040888963407ull;
    return s >> 33;
  };
  auto uni = [&](float a, float b) { return a + (b - a) * float(next() % 100000u) / 100000.0f; };
  VolumeDesc d;
  d.dims = ivec3(int(6 + next() % 14), int(6 + next() % 14), int(6 + next() % 14));
  d.spacing = vec3(uni(0.5f, 2.0f), uni(0.5f, 2.0f), uni(0.5f, 2.0f));
  Volume vol(d);
  d.type = VoxelType::U16;
  Volume lab(d);
  const vec3 c(uni(0, float(d.dims.x)), uni(0, float(d.dims.y)), uni(0, float(d.dims.z)));
  for (int z = 0; z < d.dims.z; ++z)
    for (int y = 0; y < d.dims.y; ++y)
      for (int x = 0; x < d.dims.x; ++x) {
        const float r = glm::length(vec3(x, y, z) - c);
        vol.set(x, y, z, std::max(0.0f, 255.0f - 25.0f * r) + float(next() % 8));
        lab.set(x, y, z, float(int(r / 3.0f) % 6));
      }
  const float cut = uni(0.0f, 250.0f);
  const TransferFunction tf({{0.0f, vec4(0.0f)}, {cut, vec4(0.0f)}, {cut + 1.0f, vec4(1.0f, 1.0f, 1.0f, 0.5f)},
                             {255.0f, vec4(1.0f)}});
  LabelSet enabled(6);
  for (std::uint32_t id = 1; id < 6; ++id) {
    if (next() % 2) enabled.enable(id);
  }
  const BlockGrid g = make_block_grid(d.dims, d.spacing, 4);
  const VolumeView lv = lab.view();
  const BlockMetadataTable table = compute_all_block_metadata(g, vol.view(), &lv);
  CullParams p;
  p.tf = &tf;
  p.enabled = &enabled;
  const std::vector<C> classes = classify_blocks(table, p);
  DenseGrid<std::uint8_t> iv{vol.as<std::uint8_t>(), d.dims, 1.0f / d.spacing};
  DenseGrid<std::uint16_t> lg{lab.as<std::uint16_t>(), d.dims, 1.0f / d.spacing};
  const TransferFunctionView tv = tf.view(1.0f);
  for (std::size_t i = 0; i < classes.size(); ++i) {
    const Box3 b = g.block_box(g.block_coord(i));
    for (int k = 0; k < 40; ++k) {
      vec3 f(uni(0, 1), uni(0, 1), uni(0, 1));
      if (k < 8) f = vec3(k & 1, (k >> 1) & 1, (k >> 2) & 1);  // the corners (closed box)
      const vec3 pos = b.lo + f * (b.hi - b.lo);
      const float v = iv.sample(pos);
      // The trilinear footprint lies in the dilated block: the value is within [min, max] (iso).
      RC_ASSERT(v >= table.blocks[i].min - 1e-3f && v <= table.blocks[i].max + 1e-3f);
      if (classes[i] != C::Empty) continue;
      const bool visible = enabled.enabled(lg.label_at(pos));
      RC_ASSERT(!visible || tv.lookup(v).a == 0.0f);
    }
  }
}

}  // namespace
}  // namespace sl
