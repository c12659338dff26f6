#include "apps/viewer/label_state.h"

#include <gtest/gtest.h>

namespace sl::viewer {
namespace {

TEST(LabelState, StartsUnmaskedWithAllEnabledAndTheFirstEditMasks) {
  LabelState s(10, std::nullopt);
  EXPECT_FALSE(s.masking());
  EXPECT_EQ(s.mask(), nullptr);
  EXPECT_EQ(s.enabled().count(), 10u);
  EXPECT_TRUE(s.toggle(3));
  EXPECT_TRUE(s.masking());
  ASSERT_NE(s.mask(), nullptr);
  EXPECT_FALSE(s.is_enabled(3));
  EXPECT_EQ(s.enabled().count(), 9u);
  EXPECT_TRUE(s.toggle(3));
  EXPECT_TRUE(s.is_enabled(3));
}

TEST(LabelState, AnEnableSpecStartsMasked) {
  LabelState s(10, parse_enable_spec("2,4-5", 10));
  EXPECT_TRUE(s.masking());
  EXPECT_EQ(s.enabled().ids(), (std::vector<std::uint32_t>{2, 4, 5}));
}

TEST(LabelState, BackgroundAndOutOfRangeIdsAreIgnored) {
  LabelState s(10, std::nullopt);
  const auto rev = s.revision();
  EXPECT_FALSE(s.toggle(0));
  EXPECT_FALSE(s.toggle(11));
  EXPECT_FALSE(s.set_enabled(0, true));
  EXPECT_EQ(s.revision(), rev);
  EXPECT_FALSE(s.masking());
}

TEST(LabelState, AllNoneAndMaskSwitch) {
  LabelState s(7, std::nullopt);
  s.enable_none();
  EXPECT_EQ(s.enabled().count(), 0u);
  EXPECT_TRUE(s.masking());
  s.enable_all();
  EXPECT_EQ(s.enabled().count(), 7u);
  const auto rev = s.revision();
  s.set_masking(false);
  EXPECT_EQ(s.mask(), nullptr);
  EXPECT_GT(s.revision(), rev);
  EXPECT_EQ(s.enabled().count(), 7u);  // switching the mask off keeps the set
}

TEST(LabelState, RandomFractionIsExactAndDeterministicPerSeed) {
  LabelState a(200, std::nullopt), b(200, std::nullopt), c(200, std::nullopt);
  a.random_fraction(0.25, 7);
  b.random_fraction(0.25, 7);
  c.random_fraction(0.25, 8);
  EXPECT_EQ(a.enabled().count(), 50u);
  EXPECT_EQ(a.enabled().ids(), b.enabled().ids());
  EXPECT_NE(a.enabled().ids(), c.enabled().ids());
  // The same subset as the command line's --enable fraction:P:SEED, so a view can be reproduced.
  EXPECT_EQ(a.enabled().ids(), parse_enable_spec("fraction:0.25:7", 200).ids());
  a.random_fraction(3.0, 1);  // clamped to 1
  EXPECT_EQ(a.enabled().count(), 200u);
  a.random_fraction(-1.0, 1);
  EXPECT_EQ(a.enabled().count(), 0u);
}

// A 16^3 label volume with two slabs along z: label 5 in z 4..5, label 9 in z 10..11 (x, y 4..11).
Volume two_slabs() {
  Volume v(VolumeDesc{ivec3(16), vec3(1.0f), VoxelType::U16});
  for (int z = 0; z < 16; ++z)
    for (int y = 4; y < 12; ++y)
      for (int x = 4; x < 12; ++x) {
        if (z == 4 || z == 5) v.set(x, y, z, 5.0f);
        if (z == 10 || z == 11) v.set(x, y, z, 9.0f);
      }
  return v;
}

Camera looking_down_z(float from_z) {
  Camera c;
  c.eye = vec3(8.0f, 8.0f, from_z);
  c.center = vec3(8.0f, 8.0f, 8.0f);
  c.up = vec3(0.0f, 1.0f, 0.0f);
  c.fov_deg = 20.0f;
  return c;
}

TEST(PickLabel, FirstLabelAlongThePixelRay) {
  const Volume v = two_slabs();
  // From +z the slab of label 9 is in front; from -z that of label 5.
  EXPECT_EQ(pick_label(v, looking_down_z(40.0f), 64, 64, 32, 32), 9u);
  EXPECT_EQ(pick_label(v, looking_down_z(-24.0f), 64, 64, 32, 32), 5u);
  // A corner pixel's ray misses the slabs (x, y outside 4..11), and one outside the image is nothing.
  EXPECT_EQ(pick_label(v, looking_down_z(40.0f), 64, 64, 0, 0), 0u);
  EXPECT_EQ(pick_label(v, looking_down_z(40.0f), 64, 64, 64, 10), 0u);
}

TEST(PickLabel, SkipsLabelsTheAcceptSetHides) {
  const Volume v = two_slabs();
  LabelSet only5 = parse_enable_spec("5", 9);
  EXPECT_EQ(pick_label(v, looking_down_z(40.0f), 64, 64, 32, 32, &only5), 5u);
  LabelSet none = parse_enable_spec("none", 9);
  EXPECT_EQ(pick_label(v, looking_down_z(40.0f), 64, 64, 32, 32, &none), 0u);
}

TEST(PickLabel, WorksFromInsideTheVolumeAndWithAnisotropicSpacing) {
  Volume v = two_slabs();
  v.set_spacing(vec3(1.0f, 1.0f, 2.0f));  // world z extent 32; label 5 at world z 8..12, 9 at 20..24
  Camera c;
  c.eye = vec3(8.0f, 8.0f, 16.0f);  // between the slabs, inside the box
  c.center = vec3(8.0f, 8.0f, 0.0f);
  c.up = vec3(0.0f, 1.0f, 0.0f);
  EXPECT_EQ(pick_label(v, c, 32, 32, 16, 16), 5u);
  c.center = vec3(8.0f, 8.0f, 32.0f);
  EXPECT_EQ(pick_label(v, c, 32, 32, 16, 16), 9u);
}

}  // namespace
}  // namespace sl::viewer
