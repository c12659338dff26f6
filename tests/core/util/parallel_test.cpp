// The CPU parallel loops: every index visited once (per index or per chunk), reductions exact, tiles
// covering the screen once.
#include <gtest/gtest.h>

#include <tbb/global_control.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <stdexcept>
#include <vector>

#include "core/util/parallel.h"

namespace sl {
namespace {

TEST(ParallelFor, VisitsEveryIndexOnce) {
  std::vector<std::atomic<int>> seen(10007);
  parallel_for(std::size_t(0), seen.size(), [&](std::size_t i) { ++seen[i]; });
  for (const auto& s : seen) ASSERT_EQ(s.load(), 1);
}

TEST(ParallelFor, ChunksCoverTheRangeWithoutOverlap) {
  std::vector<std::atomic<int>> seen(5000);
  std::atomic<int> chunks{0};
  parallel_for(-1000, 4000, [&](int lo, int hi) {
    ASSERT_LT(lo, hi);
    ++chunks;
    for (int i = lo; i < hi; ++i) ++seen[std::size_t(i + 1000)];
  });
  for (const auto& s : seen) ASSERT_EQ(s.load(), 1);
  EXPECT_GE(chunks.load(), 1);
}

TEST(ParallelFor, EmptyRangeCallsNothing) {
  int calls = 0;
  parallel_for(5, 5, [&](int) { ++calls; });
  parallel_for(std::int64_t(3), std::int64_t(3), [&](std::int64_t, std::int64_t) { ++calls; });
  EXPECT_EQ(calls, 0);
}

// TBB rethrows a body's exception in the caller, and so does the std::thread path of ThreadSanitizer
// builds (core/util/parallel.h): the input errors thrown inside loops reach the one catch in apps/.
TEST(ParallelFor, AnExceptionInABodyReachesTheCaller) {
  std::atomic<int> calls{0};
  EXPECT_THROW(parallel_for(0, 1000, [&](int i) {
                 ++calls;
                 if (i == 500) throw std::runtime_error("bad index");
               }),
               std::runtime_error);
  EXPECT_GE(calls.load(), 1);
  EXPECT_THROW(parallel_for_tiles(64, 64, [](int x0, int y0, int, int) {
                 if (x0 == 16 && y0 == 32) throw std::runtime_error("bad tile");
               }),
               std::runtime_error);
}

TEST(ParallelReduce, SumsAndMaximaAreExactForAnyThreadCount) {
  const std::uint64_t n = 1'000'003;
  const auto sum = [&] {
    return parallel_reduce(
        std::uint64_t(0), n, std::uint64_t(1) << 10, std::uint64_t(0),
        [](std::uint64_t lo, std::uint64_t hi, std::uint64_t acc) {
          for (std::uint64_t i = lo; i < hi; ++i) acc += i * i % 977;
          return acc;
        },
        [](std::uint64_t a, std::uint64_t b) { return a + b; });
  };
  std::uint64_t expected = 0;
  for (std::uint64_t i = 0; i < n; ++i) expected += i * i % 977;
  EXPECT_EQ(sum(), expected);
  {
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    EXPECT_EQ(sum(), expected);
  }
  const int top = parallel_reduce(
      0, 1000, 7, -1, [](int, int hi, int m) { return std::max(m, hi - 1); },
      [](int a, int b) { return std::max(a, b); });
  EXPECT_EQ(top, 999);
}

TEST(ParallelForTiles, TilesCoverEveryPixelOnceAndAreAtMostTheTileSize) {
  for (const auto& size : {std::pair{1, 1}, std::pair{16, 16}, std::pair{17, 33}, std::pair{100, 7}}) {
    const int w = size.first, h = size.second;  // not a structured binding: clang 14 cannot capture those
    std::vector<std::atomic<int>> px(std::size_t(w) * std::size_t(h));
    parallel_for_tiles(w, h, [&](int x0, int y0, int x1, int y1) {
      ASSERT_LE(x1 - x0, kTileSize);
      ASSERT_LE(y1 - y0, kTileSize);
      EXPECT_EQ(x0 % kTileSize, 0);
      EXPECT_EQ(y0 % kTileSize, 0);
      for (int y = y0; y < y1; ++y)
        for (int x = x0; x < x1; ++x) ++px[std::size_t(y) * std::size_t(w) + std::size_t(x)];
    });
    for (const auto& p : px) ASSERT_EQ(p.load(), 1) << w << "x" << h;
  }
}

}  // namespace
}  // namespace sl
