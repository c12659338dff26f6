// The CPU's parallel loops (STYLE.md #4), TBB underneath, and the screen tile size, chosen here once
// for the caster and the segment-list builder. Every loop splits work so that no result depends on
// how TBB schedules it: images and data sets are identical for any thread count.
#pragma once

#include <tbb/blocked_range.h>
#include <tbb/blocked_range2d.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <memory>
#include <type_traits>

namespace sl {

// Screen tile edge in pixels: the caster's unit of work (parallel_for_tiles) and the CPU
// segment-list builder's binning tile (paper §7: boxes are rasterized per tile).
inline constexpr int kTileSize = 16;

// Calls fn(i) for every i in [begin, end) in parallel; or, when fn takes two indices, fn(lo, hi) for
// consecutive subranges that cover [begin, end) (for work that sets up scratch space once per chunk).
// Chunks are TBB's default split (grain 1): each index must be independent of the others.
template <class Int, class Fn>
void parallel_for(Int begin, Int end, Fn&& fn) {
  tbb::parallel_for(tbb::blocked_range<Int>(begin, end, 1), [&](const tbb::blocked_range<Int>& r) {
    if constexpr (std::is_invocable_v<Fn&, Int, Int>) {
      fn(r.begin(), r.end());
    } else {
      for (Int i = r.begin(); i != r.end(); ++i) fn(i);
    }
  });
}

// Folds [begin, end) in parallel: acc = fn(lo, hi, acc) over subranges of at least `grain` indices,
// partial results joined by combine(a, b). TBB splits and joins differently from run to run, so
// combine must give the same answer in any order and grouping: integer sums, min, max, counts. (A
// float sum would not; it needs a fixed split.)
template <class Int, class T, class Fn, class Combine>
T parallel_reduce(Int begin, Int end, Int grain, T identity, Fn&& fn, Combine&& combine) {
  return tbb::parallel_reduce(
      tbb::blocked_range<Int>(begin, end, grain), identity,
      [&](const tbb::blocked_range<Int>& r, T acc) { return fn(r.begin(), r.end(), acc); }, combine);
}

// Calls fn(x0, y0, x1, y1) for every kTileSize² screen tile, in parallel. Work per pixel must not
// depend on the tile split, so images are identical for any thread count.
template <class Fn>
void parallel_for_tiles(int width, int height, Fn&& fn) {
  const int tx = (width + kTileSize - 1) / kTileSize;
  const int ty = (height + kTileSize - 1) / kTileSize;
  tbb::parallel_for(tbb::blocked_range2d<int>(0, ty, 1, 0, tx, 1), [&](const tbb::blocked_range2d<int>& r) {
    for (int j = r.rows().begin(); j < r.rows().end(); ++j) {
      for (int i = r.cols().begin(); i < r.cols().end(); ++i) {
        const int x0 = i * kTileSize, y0 = j * kTileSize;
        fn(x0, y0, x0 + kTileSize < width ? x0 + kTileSize : width,
           y0 + kTileSize < height ? y0 + kTileSize : height);
      }
    }
  });
}

// Caps the threads of every parallel loop while it lives (the commands' --threads); 0: all cores.
class ThreadLimit {
 public:
  explicit ThreadLimit(int threads) {
    if (threads > 0) {
      control_ = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                       std::size_t(threads));
    }
  }

 private:
  std::unique_ptr<tbb::global_control> control_;
};

}  // namespace sl
