// The one CPU parallel loop (STYLE.md #4): screen tiles over TBB, tile size chosen here.
#pragma once

#include <tbb/blocked_range2d.h>
#include <tbb/parallel_for.h>

namespace sl {

constexpr int kTileSize = 16;

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

}  // namespace sl
