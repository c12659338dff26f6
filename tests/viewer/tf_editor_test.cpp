#include "apps/viewer/tf_editor.h"

#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include <filesystem>

#include "core/util/error.h"
#include "tests/test_util.h"

namespace sl::viewer {
namespace {

TransferFunction ramp() {
  return TransferFunction({{10.0f, {0.0f, 0.0f, 0.0f, 0.0f}}, {200.0f, {1.0f, 0.5f, 0.25f, 0.8f}}});
}

bool sorted_and_in_range(const TfEditor& e) {
  const auto& p = e.points();
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (p[i].value < e.lo() || p[i].value > e.hi()) return false;
    if (i > 0 && p[i].value < p[i - 1].value) return false;
    for (int k = 0; k < 4; ++k) {
      if (!(p[i].rgba[k] >= 0.0f && p[i].rgba[k] <= 1.0f)) return false;
    }
  }
  return true;
}

TEST(TfEditor, InsertKeepsPointsSortedAndReturnsTheIndex) {
  TfEditor e(ramp(), 0.0f, 255.0f);
  EXPECT_EQ(e.insert(100.0f, {1, 0, 0, 0.5f}), 1);
  EXPECT_EQ(e.insert(5.0f, {0, 1, 0, 0.1f}), 0);
  EXPECT_EQ(e.insert(250.0f, {0, 0, 1, 0.9f}), 4);
  ASSERT_EQ(e.points().size(), 5u);
  EXPECT_TRUE(sorted_and_in_range(e));
  EXPECT_FLOAT_EQ(e.points()[2].value, 100.0f);
}

TEST(TfEditor, InsertClampsValueAndColourIntoRange) {
  TfEditor e(ramp(), 0.0f, 255.0f);
  const int i = e.insert(1000.0f, {2.0f, -1.0f, 0.5f, 7.0f});
  EXPECT_FLOAT_EQ(e.points()[std::size_t(i)].value, 255.0f);
  EXPECT_EQ(e.points()[std::size_t(i)].rgba, vec4(1.0f, 0.0f, 0.5f, 1.0f));
  const int j = e.insert(-50.0f, {0, 0, 0, 0});
  EXPECT_EQ(j, 0);
  EXPECT_FLOAT_EQ(e.points()[0].value, 0.0f);
}

TEST(TfEditor, InsertAtTakesTheCurveColourAndTheGivenOpacity) {
  TfEditor e(ramp(), 0.0f, 255.0f);
  const vec4 expect = ramp().evaluate(105.0f);
  const int i = e.insert_at(105.0f, 0.3f);
  const vec4 got = e.points()[std::size_t(i)].rgba;
  EXPECT_NEAR(got.r, expect.r, 1e-6f);
  EXPECT_NEAR(got.g, expect.g, 1e-6f);
  EXPECT_NEAR(got.a, 0.3f, 1e-6f);
}

TEST(TfEditor, MoveIsClampedBetweenNeighboursSoOrderNeverChanges) {
  TfEditor e(ramp(), 0.0f, 255.0f);
  const int mid = e.insert(100.0f, {1, 1, 1, 0.5f});
  EXPECT_TRUE(e.move(mid, 500.0f, 2.0f));  // past the right neighbour (200) and above opacity 1
  EXPECT_FLOAT_EQ(e.points()[std::size_t(mid)].value, 200.0f);
  EXPECT_FLOAT_EQ(e.points()[std::size_t(mid)].rgba.a, 1.0f);
  EXPECT_TRUE(e.move(mid, -5.0f, -1.0f));  // past the left neighbour (10)
  EXPECT_FLOAT_EQ(e.points()[std::size_t(mid)].value, 10.0f);
  EXPECT_FLOAT_EQ(e.points()[std::size_t(mid)].rgba.a, 0.0f);
  EXPECT_TRUE(e.move(0, -100.0f, 0.2f));  // the first point stops at the domain's start
  EXPECT_FLOAT_EQ(e.points()[0].value, 0.0f);
  EXPECT_FALSE(e.move(7, 1.0f, 1.0f));
  EXPECT_TRUE(sorted_and_in_range(e));
  EXPECT_NO_THROW(e.build());
}

TEST(TfEditor, RemoveKeepsTwoPoints) {
  TfEditor e(ramp(), 0.0f, 255.0f);
  e.insert(50.0f, {1, 1, 1, 1});
  EXPECT_TRUE(e.remove(1));
  EXPECT_EQ(e.points().size(), 2u);
  EXPECT_FALSE(e.remove(0));
  EXPECT_FALSE(e.remove(5));
  EXPECT_EQ(e.points().size(), 2u);
}

TEST(TfEditor, SetColorClampsAndRevisionCountsEveryChange) {
  TfEditor e(ramp(), 0.0f, 255.0f);
  const auto r0 = e.revision();
  EXPECT_TRUE(e.set_color(1, {0.2f, 3.0f, -1.0f, 0.4f}));
  EXPECT_EQ(e.points()[1].rgba, vec4(0.2f, 1.0f, 0.0f, 0.4f));
  EXPECT_GT(e.revision(), r0);
  const auto r1 = e.revision();
  EXPECT_FALSE(e.set_color(9, vec4(0.0f)));
  EXPECT_FALSE(e.remove(0));
  EXPECT_EQ(e.revision(), r1);  // refused edits are not changes: no re-cull
}

TEST(TfEditor, NearestPicksInScreenSpace) {
  TfEditor e(ramp(), 0.0f, 255.0f);
  // 1 px per value unit, 100 px per unit opacity: the point at (200, 0.8) is 3 px away.
  EXPECT_EQ(e.nearest(197.0f, 0.8f, 1.0f, 100.0f, 7.0f), 1);
  EXPECT_EQ(e.nearest(100.0f, 0.5f, 1.0f, 100.0f, 7.0f), -1);
  EXPECT_EQ(e.nearest(12.0f, 0.02f, 1.0f, 100.0f, 7.0f), 0);
}

TEST(TfEditor, DomainGrowsToCoverALoadedFunctionAndOnePointGetsAPartner) {
  TfEditor e(TransferFunction({{300.0f, {1, 1, 1, 1}}}), 0.0f, 255.0f);
  EXPECT_FLOAT_EQ(e.hi(), 300.0f);
  ASSERT_EQ(e.points().size(), 2u);
  EXPECT_TRUE(sorted_and_in_range(e));
}

TEST(TfEditor, SaveThenLoadRoundTripsAndBadFilesThrowNamingThem) {
  const auto dir = test::scratch_dir();
  TfEditor e(ramp(), 0.0f, 255.0f);
  e.insert(120.0f, {0.1f, 0.2f, 0.3f, 0.4f});
  const std::string file = (dir / "tf.json").string();
  e.save(file);
  TfEditor f(default_transfer_function(0.0f, 255.0f), 0.0f, 255.0f);
  f.load(file);
  ASSERT_EQ(f.points().size(), e.points().size());
  for (std::size_t i = 0; i < e.points().size(); ++i) {
    EXPECT_NEAR(f.points()[i].value, e.points()[i].value, 1e-4f);
    for (int k = 0; k < 4; ++k) EXPECT_NEAR(f.points()[i].rgba[k], e.points()[i].rgba[k], 1e-5f);
  }
  test::write_text(dir / "bad.json", "{\"points\": [");
  try {
    f.load((dir / "bad.json").string());
    FAIL() << "expected InputError";
  } catch (const InputError& err) {
    EXPECT_NE(std::string(err.what()).find("bad.json"), std::string::npos);
  }
  EXPECT_EQ(f.points().size(), e.points().size());  // a failed load leaves the function as it was
  EXPECT_THROW(e.save((dir / "no" / "such" / "dir.json").string()), InputError);
}

// Any sequence of edits leaves a valid, sorted, in-range function that TransferFunction accepts.
RC_GTEST_PROP(TfEditorProperty, AnyEditSequenceKeepsAValidFunction, ()) {
  TfEditor e(default_transfer_function(0.0f, 255.0f), 0.0f, 255.0f);
  const int n = *rc::gen::inRange(1, 60);
  for (int k = 0; k < n; ++k) {
    const int op = *rc::gen::inRange(0, 4);
    const int size = int(e.points().size());
    const int i = *rc::gen::inRange(-1, size + 1);
    const float v = float(*rc::gen::inRange(-100, 400));
    const float a = float(*rc::gen::inRange(-50, 150)) / 100.0f;
    switch (op) {
      case 0: e.insert(v, vec4(a, 1.0f - a, 0.5f, a)); break;
      case 1: e.move(i, v, a); break;
      case 2: e.remove(i); break;
      default: e.set_color(i, vec4(a, a, a, a)); break;
    }
    RC_ASSERT(sorted_and_in_range(e));
    RC_ASSERT(e.points().size() >= TfEditor::kMinPoints);
  }
  const TransferFunction tf = e.build();
  RC_ASSERT(tf.points().size() == e.points().size());
}

TEST(ValueHistogram, CountsOnALogScaleNormalisedToOne) {
  Volume v(VolumeDesc{ivec3(4, 4, 4), vec3(1.0f), VoxelType::U8});
  for (int z = 0; z < 4; ++z)
    for (int y = 0; y < 4; ++y)
      for (int x = 0; x < 4; ++x) v.set(x, y, z, x == 0 && y == 0 ? 255.0f : 0.0f);
  const std::vector<float> h = value_histogram(v, 16, 0.0f, 255.0f);
  ASSERT_EQ(h.size(), 16u);
  EXPECT_FLOAT_EQ(h[0], 1.0f);                                   // 60 background voxels
  EXPECT_NEAR(h[15], std::log1p(4.0f) / std::log1p(60.0f), 1e-6f);  // 4 bright voxels, last bin
  for (int i = 1; i < 15; ++i) EXPECT_EQ(h[std::size_t(i)], 0.0f);
}

TEST(ValueHistogram, DataDomainIsByteRangeForU8AndDataRangeOtherwise) {
  Volume u8(VolumeDesc{ivec3(2, 2, 2), vec3(1.0f), VoxelType::U8});
  float lo = -1, hi = -1;
  data_domain(u8, lo, hi);
  EXPECT_EQ(lo, 0.0f);
  EXPECT_EQ(hi, 255.0f);
  Volume f(VolumeDesc{ivec3(2, 2, 2), vec3(1.0f), VoxelType::F32});
  f.set(0, 0, 0, -2.0f);
  f.set(1, 1, 1, 3.5f);
  data_domain(f, lo, hi);
  EXPECT_EQ(lo, -2.0f);
  EXPECT_EQ(hi, 3.5f);
}

}  // namespace
}  // namespace sl::viewer
