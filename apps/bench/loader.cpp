#include "apps/bench/loader.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <thread>

#include "apps/bench/report_columns.h"
#include "apps/render_options.h"
#include "apps/scene_loader.h"
#include "cache/brick_loader.h"
#include "cache/stores/store_url.h"
#include "core/util/printable.h"

namespace sl::app {

namespace {

using Clock = std::chrono::steady_clock;

// What one pass measured. MB are 2^20 bytes of decoded bricks as the loader hands them over (stored
// voxels, apron included, and the labels when the source has them).
struct PassResult {
  int pass = 0;  // 1-based
  std::uint64_t loaded = 0, failed = 0, retries = 0;
  std::uint64_t bytes = 0;
  double seconds = 0.0;           // from the request to the last brick collected or failed
  double p50_ms = 0.0, p95_ms = 0.0;  // request to collect, per loaded brick
  std::string first_failure;      // what the source said of the first failed brick

  double bricks_per_s() const { return seconds > 0.0 ? double(loaded) / seconds : 0.0; }
  double mb_per_s() const { return seconds > 0.0 ? double(bytes) / double(1 << 20) / seconds : 0.0; }
};

// The CSV (a row per pass) and the JSON's per-pass arrays ("loader_pass_" + name).
using PassColumn = Column<PassResult>;
constexpr PassColumn kPassColumns[] = {
    PassColumn::field<&PassResult::pass>("pass"),
    PassColumn::field<&PassResult::loaded>("bricks"),
    PassColumn::field<&PassResult::failed>("failed"),
    PassColumn::field<&PassResult::retries>("retries"),
    PassColumn::field<&PassResult::seconds>("seconds"),
    {"bricks_per_s", [](const auto& p) -> Cell { return p.bricks_per_s(); }},
    {"mb_per_s", [](const auto& p) -> Cell { return p.mb_per_s(); }},
    PassColumn::field<&PassResult::p50_ms>("p50_ms"),
    PassColumn::field<&PassResult::p95_ms>("p95_ms"),
};

double ms_since(Clock::time_point t0, Clock::time_point t) {
  return std::chrono::duration<double, std::milli>(t - t0).count();
}

// One pass: a fresh loader is asked for every brick at once (as a view's first frame asks for all it
// misses) and the finished bricks are collected as they come, so the bound on finished bytes never
// holds the workers back for long. Latency therefore includes the wait in the queue.
PassResult run_pass(int pass, std::shared_ptr<const VolumeSource> source, const BrickLayout& layout,
                    const std::vector<BrickId>& ids, int threads, int& threads_used) {
  BrickLoader loader(std::move(source), layout, threads);
  threads_used = loader.threads();
  PassResult r;
  r.pass = pass;
  std::vector<double> latency_ms;
  latency_ms.reserve(ids.size());
  const Clock::time_point t0 = Clock::now();
  if (loader.request(ids) != ids.size()) throw std::logic_error("bench --loader: a fresh loader refused a brick");
  std::uint64_t settled = 0;
  Clock::time_point last = t0;
  while (settled < ids.size()) {
    LoaderBatch batch = loader.collect(std::numeric_limits<std::size_t>::max());
    const Clock::time_point now = Clock::now();
    for (LoadedBrick& b : batch.bricks) {
      r.bytes += b.intensity.size() + b.labels.size();
      latency_ms.push_back(ms_since(t0, now));
      loader.recycle(std::move(b));
    }
    for (const BrickFailure& f : batch.failures) {
      if (r.first_failure.empty()) r.first_failure = f.reason;
    }
    r.loaded += batch.bricks.size();
    r.failed += batch.failures.size();
    const std::uint64_t got = batch.bricks.size() + batch.failures.size();
    settled += got;
    if (got > 0) {
      last = now;
      continue;
    }
    // pending() first: once it is 0 nothing is loading, so failed_count() can no longer grow. Every
    // brick asked for is either collected or failed exactly once; anything else is a loader bug.
    if (loader.pending() == 0 && loader.failed_count() == r.failed) {
      throw std::logic_error("bench --loader: the loader went idle with bricks neither loaded nor failed");
    }
    // The loader has no blocking collect; a short sleep keeps this thread off the cores the workers
    // decode on (a busy loop would take one of them), at the cost of up to this much added latency.
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  r.seconds = ms_since(t0, last) / 1000.0;
  r.p50_ms = percentile(latency_ms, 0.50);
  r.p95_ms = percentile(latency_ms, 0.95);
  r.retries = loader.counts().retries;
  return r;
}

double median_of(const std::vector<PassResult>& passes, double (*of)(const PassResult&)) {
  std::vector<double> v;
  for (const PassResult& p : passes) v.push_back(of(p));
  return percentile(v, 0.5);
}

void print_pass(const PassResult& p) {
  std::printf("%5d %8llu %7llu %8llu %9.3f %10.1f %9.1f %9.1f %9.1f\n", p.pass, (unsigned long long)p.loaded,
              (unsigned long long)p.failed, (unsigned long long)p.retries, p.seconds, p.bricks_per_s(), p.mb_per_s(),
              p.p50_ms, p.p95_ms);
}

}  // namespace

std::vector<BrickId> centre_first_bricks(const BrickLayout& layout, std::uint64_t count) {
  using glm::dvec3;
  const ivec3 n = layout.bricks(0), dims = layout.dims(0);
  const int b = layout.brick_size;
  const dvec3 spacing(layout.spacing);
  const dvec3 centre = dvec3(dims) * 0.5 * spacing;
  const std::uint64_t total = layout.brick_count(0);
  count = std::min(count, total);
  // The payload's centre: the last brick along an axis may be cut short by the volume's edge.
  const auto distance2 = [&](ivec3 c) {
    const ivec3 lo = c * b, hi = glm::min(lo + b, dims);
    const dvec3 d = (dvec3(lo + hi) * 0.5) * spacing - centre;
    return glm::dot(d, d);
  };
  // Every brick whose centre lies within radius r of the volume's centre is in the box of bricks
  // around it computed below (a brick's centre lies inside the brick); once that ball holds `count`
  // bricks, they are the nearest. The ball starts a little larger than `count` bricks' volume and
  // doubles until it holds enough or the box is the whole level.
  const double brick_volume = double(b) * b * b * spacing.x * spacing.y * spacing.z;
  const double brick_diagonal = double(b) * glm::length(spacing);
  double r = 1.25 * std::cbrt(double(count) * brick_volume * 3.0 / (4.0 * std::numbers::pi)) + brick_diagonal;
  struct Candidate {
    double d2;
    BrickId id;
  };
  std::vector<Candidate> near;
  for (;;) {
    const dvec3 lo_v = (centre - r) / spacing, hi_v = (centre + r) / spacing;
    const ivec3 lo = glm::clamp(ivec3(glm::floor(lo_v / double(b))), ivec3(0), n - 1);
    const ivec3 hi = glm::clamp(ivec3(glm::floor(hi_v / double(b))), ivec3(0), n - 1);
    const bool whole = lo == ivec3(0) && hi == n - 1;
    near.clear();
    for (int z = lo.z; z <= hi.z; ++z) {
      for (int y = lo.y; y <= hi.y; ++y) {
        for (int x = lo.x; x <= hi.x; ++x) {
          const ivec3 c(x, y, z);
          const double d2 = distance2(c);
          if (whole || d2 <= r * r) near.push_back({d2, BrickId::pack(0, c)});
        }
      }
    }
    if (whole || near.size() >= count) break;
    r *= 2.0;
  }
  const auto nearer = [](const Candidate& a, const Candidate& c) { return a.d2 != c.d2 ? a.d2 < c.d2 : a.id < c.id; };
  std::nth_element(near.begin(), near.begin() + std::ptrdiff_t(count - 1), near.end(), nearer);
  near.resize(count);
  std::sort(near.begin(), near.end(), nearer);
  std::vector<BrickId> ids;
  ids.reserve(near.size());
  for (const Candidate& c : near) ids.push_back(c.id);
  return ids;
}

int bench_loader(const BenchOptions& o, OutputFiles& outputs) {
  const RenderOptions& ro = o.render;
  const OutOfCoreSettings os = out_of_core_settings(ro);
  SourceScene scene = load_source_scene(ro.scene, true, shows_labels(ro));
  // The renderer's layout (cache/out_of_core/renderer.cpp): the same bricks, so the same reads.
  const BrickLayout layout = BrickLayout::make(scene.source->desc(), os.brick, scene.source->name());
  const std::vector<BrickId> ids = centre_first_bricks(layout, std::uint64_t(o.loader_bricks));
  const ivec3 grid = layout.bricks(0);
  std::printf("bench (loader): %s, %zu level-0 bricks of %d^3 (of %dx%dx%d), centre first, %d passes\n",
              scene.name.c_str(), ids.size(), layout.brick_size, grid.x, grid.y, grid.z, o.loader_passes);
  if (ids.size() < std::size_t(o.loader_bricks)) {
    std::printf("the volume has only %zu level-0 bricks (--loader-bricks %d): loading all of them\n", ids.size(),
                o.loader_bricks);
  }
  std::vector<PassResult> passes;
  int threads = 0;
  for (int p = 1; p <= o.loader_passes; ++p) {
    // A streamed source keeps decoded chunks between reads: a fresh one per pass makes every pass
    // read the store as the first does. A volume in memory has nothing to forget. The old one is
    // closed first, so two disk caches never index the same directory at once.
    if (p > 1 && !scene.volume) {
      scene = SourceScene{};
      set_disk_cache(nullptr);
      scene = load_source_scene(ro.scene, true, shows_labels(ro));
    }
    passes.push_back(run_pass(p, scene.source, layout, ids, ro.threads, threads));
    if (p == 1) {
      std::printf("%d loader threads\n%5s %8s %7s %8s %9s %10s %9s %9s %9s\n", threads, "pass", "bricks", "failed",
                  "retries", "seconds", "bricks/s", "MB/s", "p50 ms", "p95 ms");
    }
    print_pass(passes.back());
  }
  const double bricks_per_s = median_of(passes, [](const PassResult& p) { return p.bricks_per_s(); });
  const double mb_per_s = median_of(passes, [](const PassResult& p) { return p.mb_per_s(); });
  const double p50 = median_of(passes, [](const PassResult& p) { return p.p50_ms; });
  const double p95 = median_of(passes, [](const PassResult& p) { return p.p95_ms; });
  std::uint64_t failed = 0;
  std::string first_failure;
  for (const PassResult& p : passes) {
    failed = std::max(failed, p.failed);
    if (first_failure.empty()) first_failure = p.first_failure;
  }
  std::printf("median: %.1f bricks/s, %.1f MB/s, latency p50 %.1f ms, p95 %.1f ms; %llu failed (most in a pass), "
              "%d threads\n",
              bricks_per_s, mb_per_s, p50, p95, (unsigned long long)failed, threads);
  if (!first_failure.empty()) std::printf("first failure: %s\n", printable(first_failure).c_str());
  if (const std::string remote = remote_summary(); !remote.empty()) std::printf("%s\n", remote.c_str());

  nlohmann::json js;
  js["volume"] = scene.name;
  js["brick"] = layout.brick_size;
  js["loader_threads"] = threads;
  js["loader_bricks"] = ids.size();
  js["loader_bricks_requested"] = o.loader_bricks;
  js["loader_passes"] = o.loader_passes;
  js["loader_bricks_per_s"] = bricks_per_s;
  js["loader_mb_per_s"] = mb_per_s;
  js["loader_p50_ms"] = p50;
  js["loader_p95_ms"] = p95;
  js["loader_failed"] = failed;
  std::ostringstream csv;
  write_csv_header(csv, kPassColumns);
  for (const PassResult& p : passes) {
    write_csv_row(csv, kPassColumns, p);
    nlohmann::json row;
    add_json_fields(row, kPassColumns, p);
    for (const auto& [key, value] : row.items()) js["loader_pass_" + key].push_back(value);
  }
  write_reports(o, outputs, csv.str(), js.dump(2) + "\n");
  return 0;
}

}  // namespace sl::app
