// The CPU's parallel loops (STYLE.md #4), TBB underneath, and the screen tile size, chosen here once
// for the caster and the segment-list builder. Every loop splits work so that no result depends on
// how TBB schedules it: images and data sets are identical for any thread count.
//
// Under ThreadSanitizer (SL_SANITIZE=thread) the loops run on std::threads instead (fork_join below):
// Debian's TBB is not instrumented, so TSan cannot see the happens-before edges of its joins and
// would report every loop body as racing with the code after the loop. With plain threads the joins
// are std::thread::join, which TSan understands, and no suppression is needed. Because no result may
// depend on the split (the rule above), both paths give the same images.
#pragma once

#include <tbb/blocked_range.h>
#include <tbb/blocked_range2d.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <memory>
#include <type_traits>

#if defined(__SANITIZE_THREAD__)
#define SL_PARALLEL_STD_THREADS 1
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define SL_PARALLEL_STD_THREADS 1
#endif
#endif

#ifdef SL_PARALLEL_STD_THREADS
#include <algorithm>
#include <atomic>
#include <cstdint>
#include <exception>
#include <mutex>
#include <thread>
#include <utility>
#include <vector>
#endif

namespace sl {

// Screen tile edge in pixels: the caster's unit of work (parallel_for_tiles) and the CPU
// segment-list builder's binning tile (paper §7: boxes are rasterized per tile).
inline constexpr int kTileSize = 16;

#ifdef SL_PARALLEL_STD_THREADS
namespace detail {

// ThreadLimit's cap for the std::thread loops; 0: all cores.
inline std::atomic<int>& thread_cap() {
  static std::atomic<int> cap{0};
  return cap;
}

inline int loop_threads() {
  const int cap = thread_cap().load();
  return cap > 0 ? cap : int(std::max(1u, std::thread::hardware_concurrency()));
}

// Calls chunk(c) for every c in [0, chunks) on up to loop_threads() threads, the caller being one;
// each takes the next chunk from a shared counter. As with TBB, the first exception a chunk throws
// stops the chunks not yet started and is rethrown here after every thread has joined.
template <class Fn>
void fork_join(std::int64_t chunks, Fn&& chunk) {
  std::atomic<std::int64_t> next{0};
  std::exception_ptr error;
  std::mutex error_mutex;
  const auto work = [&] {
    for (std::int64_t c; (c = next.fetch_add(1)) < chunks;) {
      try {
        chunk(c);
      } catch (...) {
        const std::lock_guard lock(error_mutex);
        if (!error) error = std::current_exception();
        next.store(chunks);
      }
    }
  };
  std::vector<std::thread> threads;
  for (std::int64_t t = 1; t < std::min<std::int64_t>(loop_threads(), chunks); ++t) threads.emplace_back(work);
  work();
  for (auto& t : threads) t.join();
  if (error) std::rethrow_exception(error);
}

// Chunks per thread: enough that uneven work (rays through dense and empty regions) balances.
inline constexpr std::int64_t kChunksPerThread = 8;

// [begin, end) cut into about kChunksPerThread chunks per thread of at least `grain` indices:
// chunk(lo, hi) for each.
template <class Int, class Fn>
void fork_join_range(Int begin, Int end, Int grain, Fn&& chunk) {
  if (!(begin < end)) return;
  const std::int64_t n = std::int64_t(end - begin), chunks = loop_threads() * kChunksPerThread;
  const std::int64_t size = std::max<std::int64_t>({std::int64_t(grain), 1, (n + chunks - 1) / chunks});
  fork_join((n + size - 1) / size, [&](std::int64_t c) {
    chunk(Int(begin + Int(c * size)), Int(begin + Int(std::min(n, (c + 1) * size))));
  });
}

}  // namespace detail
#endif

// Calls fn(i) for every i in [begin, end) in parallel; or, when fn takes two indices, fn(lo, hi) for
// consecutive subranges that cover [begin, end) (for work that sets up scratch space once per chunk).
// Chunks are TBB's default split (grain 1): each index must be independent of the others.
template <class Int, class Fn>
void parallel_for(Int begin, Int end, Fn&& fn) {
  const auto chunk = [&](Int lo, Int hi) {
    if constexpr (std::is_invocable_v<Fn&, Int, Int>) {
      fn(lo, hi);
    } else {
      for (Int i = lo; i != hi; ++i) fn(i);
    }
  };
#ifdef SL_PARALLEL_STD_THREADS
  detail::fork_join_range(begin, end, Int(1), chunk);
#else
  tbb::parallel_for(tbb::blocked_range<Int>(begin, end, 1),
                    [&](const tbb::blocked_range<Int>& r) { chunk(r.begin(), r.end()); });
#endif
}

// Folds [begin, end) in parallel: acc = fn(lo, hi, acc) over subranges of at least `grain` indices,
// partial results joined by combine(a, b). TBB splits and joins differently from run to run, so
// combine must give the same answer in any order and grouping: integer sums, min, max, counts. (A
// float sum would not; it needs a fixed split.)
template <class Int, class T, class Fn, class Combine>
T parallel_reduce(Int begin, Int end, Int grain, T identity, Fn&& fn, Combine&& combine) {
#ifdef SL_PARALLEL_STD_THREADS
  // One partial result per chunk, collected under a lock, combined in chunk order after the join.
  std::vector<std::pair<Int, T>> parts;
  std::mutex parts_mutex;
  detail::fork_join_range(begin, end, grain, [&](Int lo, Int hi) {
    T acc = fn(lo, hi, identity);
    const std::lock_guard lock(parts_mutex);
    parts.emplace_back(lo, std::move(acc));
  });
  std::sort(parts.begin(), parts.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  T result = identity;
  for (auto& p : parts) result = combine(result, p.second);
  return result;
#else
  return tbb::parallel_reduce(
      tbb::blocked_range<Int>(begin, end, grain), identity,
      [&](const tbb::blocked_range<Int>& r, T acc) { return fn(r.begin(), r.end(), acc); }, combine);
#endif
}

// Calls fn(x0, y0, x1, y1) for every kTileSize² screen tile, in parallel. Work per pixel must not
// depend on the tile split, so images are identical for any thread count.
template <class Fn>
void parallel_for_tiles(int width, int height, Fn&& fn) {
  const int tx = (width + kTileSize - 1) / kTileSize;
  const int ty = (height + kTileSize - 1) / kTileSize;
  const auto tile = [&](int i, int j) {
    const int x0 = i * kTileSize, y0 = j * kTileSize;
    fn(x0, y0, x0 + kTileSize < width ? x0 + kTileSize : width, y0 + kTileSize < height ? y0 + kTileSize : height);
  };
#ifdef SL_PARALLEL_STD_THREADS
  detail::fork_join(std::int64_t(tx) * ty, [&](std::int64_t t) { tile(int(t % tx), int(t / tx)); });
#else
  tbb::parallel_for(tbb::blocked_range2d<int>(0, ty, 1, 0, tx, 1), [&](const tbb::blocked_range2d<int>& r) {
    for (int j = r.rows().begin(); j < r.rows().end(); ++j) {
      for (int i = r.cols().begin(); i < r.cols().end(); ++i) tile(i, j);
    }
  });
#endif
}

// Caps the threads of every parallel loop while it lives (the commands' --threads); 0: all cores.
class ThreadLimit {
 public:
#ifdef SL_PARALLEL_STD_THREADS
  explicit ThreadLimit(int threads) : previous_(detail::thread_cap().load()) {
    if (threads > 0) detail::thread_cap().store(threads);
  }
  ~ThreadLimit() { detail::thread_cap().store(previous_); }
  ThreadLimit(const ThreadLimit&) = delete;
  ThreadLimit& operator=(const ThreadLimit&) = delete;

 private:
  int previous_;
#else
  explicit ThreadLimit(int threads) {
    if (threads > 0) {
      control_ = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                       std::size_t(threads));
    }
  }

 private:
  std::unique_ptr<tbb::global_control> control_;
#endif
};

}  // namespace sl
