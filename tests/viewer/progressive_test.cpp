// Progressive rendering's plain parts (apps/viewer/progressive.h): the pixel levels, the choice of the
// moving level from measured frame times, the frame rate and the overlay rows.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>

#include "apps/viewer/progressive.h"

namespace sl::viewer {
namespace {

TEST(ProgressiveLevels, LevelsHalveThePixels) {
  EXPECT_EQ(level_label(0), "1");
  EXPECT_EQ(level_label(1), "1/2");
  EXPECT_EQ(level_label(2), "1/4");
  EXPECT_EQ(level_label(kCoarsestLevel), "1/64");
  EXPECT_FLOAT_EQ(level_scale(0), 1.0f);
  EXPECT_FLOAT_EQ(level_scale(2), 0.5f);
  EXPECT_FLOAT_EQ(level_scale(6), 0.125f);
  EXPECT_EQ(level_extent(800, 0), 800);
  EXPECT_EQ(level_extent(800, 2), 400);
  EXPECT_EQ(level_extent(600, 1), 424);  // 600 / sqrt(2)
  EXPECT_EQ(level_extent(600, 6), 75);
  EXPECT_EQ(level_extent(3, 6), 1);  // never empty
}

// Frame time as fixed costs plus a cost per pixel, in ms at each level.
std::function<double(int)> affine_cost(double fixed, double full_pixels) {
  return [=](int level) { return fixed + full_pixels * std::ldexp(1.0, -level); };
}

// Runs `frames` moving frames against `cost` and returns the level of the last.
int settle(ProgressiveLevels& p, const std::function<double(int)>& cost, int frames) {
  for (int i = 0; i < frames; ++i) p.observe(p.moving_level(), cost(p.moving_level()));
  return p.moving_level();
}

TEST(ProgressiveLevels, NothingIsPredictedBeforeAFrameIsMeasured) {
  const ProgressiveLevels p(80.0);
  EXPECT_LT(p.predicted_ms(0), 0.0);
  EXPECT_EQ(p.moving_level(), 2);
}

TEST(ProgressiveLevels, SettlesOnTheFinestLevelThatHoldsTheBudgetAndStays) {
  ProgressiveLevels p(80.0);
  const auto cost = affine_cost(20.0, 400.0);  // 420 ms full; 70 ms at 1/8, 120 ms at 1/4
  p.observe(0, cost(0));                      // the still frame comes first
  EXPECT_EQ(p.moving_level(), 3);
  for (int i = 0; i < 20; ++i) {
    p.observe(p.moving_level(), cost(p.moving_level()));
    EXPECT_EQ(p.moving_level(), 3) << "frame " << i;  // no flipping between levels
  }
}

TEST(ProgressiveLevels, FromCoarseItStepsFinerOnlyWithMargin) {
  ProgressiveLevels p(80.0);
  const auto cost = affine_cost(20.0, 400.0);
  p.observe(kCoarsestLevel, cost(kCoarsestLevel));  // 26 ms: proportional prediction says 1/4 is 105 ms
  const int level = settle(p, cost, 10);
  EXPECT_LE(cost(level), 80.0);
  // Finer than `level` would not fit with the margin that keeps noise from flipping levels.
  EXPECT_TRUE(level == 0 || cost(level - 1) > 80.0 * ProgressiveLevels::kFinerMargin) << level;
  EXPECT_LE(level, 4);
}

TEST(ProgressiveLevels, ADearerViewGoesCoarserAndACheaperOneFiner) {
  ProgressiveLevels p(80.0);
  p.observe(0, 420.0);
  EXPECT_EQ(settle(p, affine_cost(20.0, 400.0), 5), 3);
  const auto dear = affine_cost(40.0, 1200.0);  // zoomed in: 3x the samples per pixel
  const int coarser = settle(p, dear, 4);
  EXPECT_GT(coarser, 3);
  EXPECT_LE(dear(coarser), 80.0);
  const auto cheap = affine_cost(5.0, 100.0);  // 105 ms full, 55 ms at 1/2
  const int finer = settle(p, cheap, 6);
  EXPECT_EQ(finer, 1);
}

TEST(ProgressiveLevels, FullResolutionWhenItFitsCoarsestWhenNothingDoes) {
  ProgressiveLevels fast(80.0);
  EXPECT_EQ(settle(fast, affine_cost(2.0, 30.0), 4), 0);
  ProgressiveLevels slow(80.0);
  EXPECT_EQ(settle(slow, affine_cost(100.0, 30.0), 8), kCoarsestLevel);  // fixed costs over the budget
}

TEST(ProgressiveSchedule, ChangesFirstThenRefineOnceStillAndIdle) {
  // changed, interacting, last level, worker idle, full frame still loading
  EXPECT_EQ(next_submission(true, true, 3, false, false), Submission::Changed);  // dragging: coarse, latest wins
  EXPECT_EQ(next_submission(true, false, 0, true, true), Submission::Changed);   // a key or label toggle
  EXPECT_EQ(next_submission(false, true, 3, true, false), Submission::None);     // held still mid-drag
  EXPECT_EQ(next_submission(false, false, 3, false, false), Submission::None);   // coarse frame not shown yet
  EXPECT_EQ(next_submission(false, false, 3, true, false), Submission::Refine);  // released: full resolution
  EXPECT_EQ(next_submission(false, false, 0, true, false), Submission::None);    // full frame shown: done
  EXPECT_EQ(next_submission(false, false, 0, true, true), Submission::Repeat);   // out of core: bricks stream in
  EXPECT_EQ(next_submission(false, false, 0, false, true), Submission::None);
}

TEST(FrameRate, CountsFramesOverTheLastSecond) {
  FrameRate r;
  EXPECT_EQ(r.fps(0.0), 0.0);
  for (int i = 0; i <= 30; ++i) r.tick(0.1 * i);
  EXPECT_NEAR(r.fps(3.0), 10.0, 0.01);
  EXPECT_EQ(r.fps(4.5), 0.0);  // nothing new for over a second: no frames are coming
}

TEST(FrameRate, RowsShowTheLevelAndTheRate) {
  const std::vector<StatRow> on = progressive_rows(true, 2, 9.54, 80.0);
  ASSERT_EQ(on.size(), 4u);
  EXPECT_TRUE(on[0].heading);
  EXPECT_EQ(on[1].label, "pixels");
  EXPECT_EQ(on[1].value, "1/4");
  EXPECT_EQ(on[2].label, "frames/s");
  EXPECT_EQ(on[2].value, "9.5");
  EXPECT_EQ(on[3].value, "80");
  const std::vector<StatRow> off = progressive_rows(false, 0, 2.0, 80.0);
  ASSERT_EQ(off.size(), 3u);
  EXPECT_EQ(off[1].value, "1 (off)");
}

}  // namespace
}  // namespace sl::viewer
