// Enabled-label sets, the --enable syntax and label colours.
#include "core/scene/labels.h"

#include <gtest/gtest.h>

#include <set>

#include "core/util/error.h"

namespace sl {
namespace {

TEST(Labels, AllNoneListsAndRanges) {
  EXPECT_EQ(parse_enable_spec("all", 20).count(), 20u);
  EXPECT_FALSE(parse_enable_spec("all", 20).enabled(0));
  EXPECT_EQ(parse_enable_spec("none", 20).count(), 0u);
  const LabelSet s = parse_enable_spec(" 1, 5,10-20 ", 20);
  EXPECT_EQ(s.count(), 13u);
  EXPECT_EQ(s.ids().front(), 1u);
  EXPECT_TRUE(s.enabled(5));
  EXPECT_TRUE(s.enabled(10));
  EXPECT_TRUE(s.enabled(20));
  EXPECT_FALSE(s.enabled(9));
  EXPECT_FALSE(s.enabled(21));
  EXPECT_FALSE(s.enabled(100000));  // beyond the set: not enabled
}

TEST(Labels, BadSpecsThrowNamingTheOption) {
  for (const char* bad : {"", "abc", "5-3", "0", "0-4", "21", "1,,2", "1-", "-3", "fraction:2:1", "fraction:x:1",
                          "fraction:0.5:seed", "3.5"}) {
    try {
      parse_enable_spec(bad, 20);
      FAIL() << "accepted '" << bad << "'";
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), "--enable") << bad;
    }
  }
}

TEST(Labels, FractionIsExactDeterministicAndNested) {
  const LabelSet a = parse_enable_spec("fraction:0.25:7", 1000);
  EXPECT_EQ(a.count(), 250u);
  EXPECT_EQ(a.ids(), parse_enable_spec("fraction:0.25:7", 1000).ids());
  EXPECT_NE(a.ids(), parse_enable_spec("fraction:0.25:8", 1000).ids());
  const LabelSet b = parse_enable_spec("fraction:0.5:7", 1000);
  for (std::uint32_t id : a.ids()) EXPECT_TRUE(b.enabled(id));  // grows with P for one seed
  EXPECT_EQ(parse_enable_spec("fraction:0:7", 1000).count(), 0u);
  EXPECT_EQ(parse_enable_spec("fraction:1:7", 1000).count(), 1000u);
  EXPECT_FALSE(parse_enable_spec("fraction:1:7", 1000).enabled(0));
}

TEST(Labels, SetAndViewAgree) {
  LabelSet s(10);
  s.enable(0);  // background: ignored
  s.enable(3);
  s.enable(3);
  s.enable(70);  // grows
  EXPECT_EQ(s.count(), 2u);
  EXPECT_GE(s.size(), 71u);
  const LabelSetView v = s.view();
  for (std::uint32_t id = 0; id < 100; ++id) EXPECT_EQ(v.enabled(id), id == 3 || id == 70) << id;
  s.disable(3);
  EXPECT_EQ(s.count(), 1u);
  EXPECT_TRUE(s.any_enabled(std::vector<std::uint32_t>{1, 70}));
  EXPECT_FALSE(s.any_enabled(std::vector<std::uint32_t>{0, 3}));
}

TEST(Labels, ColoursAreStableDistinctAndInRange) {
  EXPECT_EQ(label_color(0), vec3(0.0f));
  std::set<std::tuple<float, float, float>> seen;
  float min_dist = 1e9f;
  for (std::uint32_t id = 1; id <= 64; ++id) {
    const vec3 c = label_color(id);
    EXPECT_EQ(c, label_color(id));
    for (int k = 0; k < 3; ++k) {
      EXPECT_GE(c[k], 0.0f);
      EXPECT_LE(c[k], 1.0f);
    }
    EXPECT_GT(glm::max(c.r, glm::max(c.g, c.b)), 0.7f);  // bright enough to see
    seen.insert({c.r, c.g, c.b});
    for (std::uint32_t j = 1; j < id; ++j) min_dist = std::min(min_dist, glm::length(c - label_color(j)));
  }
  EXPECT_EQ(seen.size(), 64u);
  EXPECT_GT(min_dist, 0.01f);
  // Consecutive ids differ clearly (neighbouring segments must be told apart).
  for (std::uint32_t id = 1; id < 200; ++id) EXPECT_GT(glm::length(label_color(id) - label_color(id + 1)), 0.05f) << id;
}

TEST(Labels, HugeLabelIdsAreRefusedWithTheTableSize) {
  EXPECT_NO_THROW(check_label_table(kMaxLabelId, "l.nrrd"));
  for (std::uint32_t id : {kMaxLabelId + 1u, 0xFFFFFFFEu, 0xFFFFFFFFu}) {
    try {
      check_label_table(id, "l.nrrd");
      ADD_FAILURE() << id;
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), "l.nrrd");
      EXPECT_NE(std::string(e.what()).find(std::to_string(id)), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("MiB"), std::string::npos) << e.what();
    }
  }
  EXPECT_NE(std::string([] {
              try { check_label_table(0xFFFFFFFFu, "x"); } catch (const InputError& e) { return std::string(e.what()); }
              return std::string();
            }()).find("512 MiB"),
            std::string::npos);
}

}  // namespace
}  // namespace sl
