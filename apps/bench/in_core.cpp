// `sparseleap bench` in core: per method a fresh renderer replays the path, each view twice (lists
// rebuilt, then reused); a summary table, a CSV row per frame, a JSON object per method.
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <sstream>

#include "apps/bench/bench_run.h"
#include "apps/bench/report_columns.h"

namespace sl::app {

// A method's figures over the path, named as the keys of its JSON object. Times and depth complexity
// of the rasterization frames; `median_ms_without_rasterization` of the frames that reused their lists.
struct InCoreSummary {
  double median_ms = 0, p95_ms = 0, median_ms_without_rasterization = 0, median_raycast_ms = 0, median_lists_ms = 0;
  double speedup_vs_none = 0;  // over the median of method none (0 without it)
  std::uint64_t samples = 0, useful_samples = 0, occupancy_misses = 0;
  double sample_efficiency = 0;  // useful samples over samples
  double depth_complexity_avg = 0;
  std::uint32_t depth_complexity_max = 0;
};
// The JSON: an object per method (outside the anonymous namespace: its from_json is unused).
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(InCoreSummary, median_ms, p95_ms, median_ms_without_rasterization,
                                   median_raycast_ms, median_lists_ms, speedup_vs_none, samples, useful_samples,
                                   sample_efficiency, occupancy_misses, depth_complexity_avg, depth_complexity_max)

namespace {

// A frame of the path, rendered with its lists rebuilt (rasterization) or reused (only the
// opacity scaled).
struct FrameRecord {
  const char* method = "";
  int frame = 0;
  bool rasterization = true;
  Stats stats;
};

// The CSV: a row per method and frame.
using FrameColumn = Column<FrameRecord>;
constexpr FrameColumn kInCoreFrameColumns[] = {
    {"method", [](const auto& r) -> Cell { return r.method; }},
    {"frame", [](const auto& r) -> Cell { return r.frame; }},
    {"rasterization", [](const auto& r) -> Cell { return r.rasterization ? 1 : 0; }},
    FrameColumn::stat("total_ms"), FrameColumn::stat("metadata_ms"), FrameColumn::stat("tree_ms"),
    FrameColumn::stat("geometry_ms"), FrameColumn::stat("order_ms"), FrameColumn::stat("lists_ms"),
    FrameColumn::stat("raycast_ms"), FrameColumn::stat("samples"), FrameColumn::stat("useful_samples"),
    FrameColumn::stat("depth_complexity_avg"), FrameColumn::stat("depth_complexity_max"), FrameColumn::stat("boxes"),
    FrameColumn::stat("events"), FrameColumn::stat("occupancy_misses"),
};

// Per method a fresh renderer replays the path; every view is rendered twice, once with its
// lists rebuilt and once with only the opacity scaled (the lists reused: the paper's "w/o
// rasterization"). A record per method and frame.
std::vector<std::vector<FrameRecord>> render_in_core(BenchRun& b, std::unique_ptr<SceneRenderer> first) {
  const TransferFunction dimmer = b.scene.tf.scaled_opacity(0.8f);
  const bool tty = ::isatty(2);
  std::vector<std::vector<FrameRecord>> records(b.methods.size());
  for (std::size_t mi = 0; mi < b.methods.size(); ++mi) {
    const std::unique_ptr<SceneRenderer> renderer = b.renderer_for(mi, first);
    const char* method = to_string(b.rs.method);
    for (int w = 0; w < b.warmup; ++w) renderer->render(b.scene.tf, b.enabled(), b.path.at(0), b.rs);
    for (int f = 0; f < b.path.frames; ++f) {
      renderer->invalidate_lists();  // a rasterization frame always rebuilds its lists
      records[mi].push_back({method, f, true, renderer->render(b.scene.tf, b.enabled(), b.path.at(f), b.rs).stats});
      // Same view, opacity scaled: the block classes are unchanged, so the lists are reused.
      records[mi].push_back({method, f, false, renderer->render(dimmer, b.enabled(), b.path.at(f), b.rs).stats});
      if (tty) {
        std::fprintf(stderr, "\r  %-10s frame %d/%d  %.1f ms   ", method, f + 1, b.path.frames,
                     records[mi][records[mi].size() - 2].stats.time_ms.total);
      }
    }
    if (tty) std::fprintf(stderr, "\r%60s\r", "");
  }
  return records;
}

InCoreSummary summarize(const std::vector<FrameRecord>& recs) {
  InCoreSummary s;
  std::vector<double> total, norast, raycast, lists;
  double dc = 0;
  int n = 0;
  for (const FrameRecord& r : recs) {
    if (!r.rasterization) {
      norast.push_back(r.stats.time_ms.total);
      continue;
    }
    total.push_back(r.stats.time_ms.total);
    raycast.push_back(r.stats.time_ms.raycast);
    lists.push_back(r.stats.time_ms.lists + r.stats.time_ms.order);
    s.samples += r.stats.samples;
    s.useful_samples += r.stats.useful_samples;
    s.occupancy_misses += r.stats.occupancy_misses;
    dc += r.stats.depth_complexity_avg;
    s.depth_complexity_max = std::max(s.depth_complexity_max, r.stats.depth_complexity_max);
    ++n;
  }
  s.median_ms = percentile(total, 0.5);
  s.p95_ms = percentile(total, 0.95);
  s.median_ms_without_rasterization = percentile(norast, 0.5);
  s.median_raycast_ms = percentile(raycast, 0.5);
  s.median_lists_ms = percentile(lists, 0.5);
  s.depth_complexity_avg = n ? dc / n : 0.0;
  s.sample_efficiency = s.samples ? double(s.useful_samples) / double(s.samples) : 0.0;
  return s;
}

// The median of method none (0 when it was not run); speed-ups are relative to it.
double none_median_ms(const BenchRun& b, const std::vector<InCoreSummary>& sums) {
  double none_median = 0;
  for (std::size_t mi = 0; mi < b.methods.size(); ++mi) {
    if (b.methods[mi] == SkipMethod::None) none_median = sums[mi].median_ms;
  }
  return none_median;
}

void print_summary_table(const BenchRun& b, const std::vector<InCoreSummary>& sums, double none_median) {
  std::printf("%-11s %10s %10s %12s %9s %13s %11s %10s %8s %6s\n", "method", "median ms", "p95 ms", "w/o rast ms",
              "speed-up", "samples/frame", "efficiency", "lists ms", "dc avg", "dc max");
  for (std::size_t mi = 0; mi < b.methods.size(); ++mi) {
    const InCoreSummary& s = sums[mi];
    std::printf("%-11s %10.1f %10.1f %12.1f %9s %13.3g %10.2f%% %10.1f %8.2f %6u\n", to_string(b.methods[mi]),
                s.median_ms, s.p95_ms, s.median_ms_without_rasterization,
                none_median > 0 ? (std::to_string(s.speedup_vs_none).substr(0, 5) + "x").c_str() : "-",
                double(s.samples) / b.path.frames, 100.0 * s.sample_efficiency, s.median_lists_ms,
                s.depth_complexity_avg, s.depth_complexity_max);
  }
}

}  // namespace

int bench_in_core(BenchRun& b, std::unique_ptr<SceneRenderer> first) {
  std::printf("bench: %s, %dx%d, %s, %d frames x %zu methods%s\n", b.scene.name.c_str(), b.rs.width, b.rs.height,
              to_string(b.rs.mode), b.path.frames, b.methods.size(),
              b.scene.enabled ? (", " + std::to_string(b.scene.enabled->count()) + " labels enabled").c_str() : "");
  const std::vector<std::vector<FrameRecord>> records = render_in_core(b, std::move(first));
  std::vector<InCoreSummary> sums;
  for (const auto& r : records) sums.push_back(summarize(r));
  const double none_median = none_median_ms(b, sums);
  for (InCoreSummary& s : sums) {
    s.speedup_vs_none = none_median > 0 && s.median_ms > 0 ? none_median / s.median_ms : 0.0;
  }
  print_summary_table(b, sums, none_median);
  nlohmann::json js;
  js["volume"] = b.scene.name;
  js["width"] = b.rs.width;
  js["height"] = b.rs.height;
  js["mode"] = to_string(b.rs.mode);
  js["frames"] = b.path.frames;
  for (std::size_t mi = 0; mi < b.methods.size(); ++mi) {
    nlohmann::json method = nlohmann::json::object();
    method.update(nlohmann::json(sums[mi]));
    js["methods"][to_string(b.methods[mi])] = std::move(method);
  }
  std::ostringstream csv;
  if (!b.o.csv.empty()) {
    write_csv_header(csv, kInCoreFrameColumns);
    for (const auto& method_records : records) {
      for (const FrameRecord& r : method_records) write_csv_row(csv, kInCoreFrameColumns, r);
    }
  }
  write_reports(b, csv.str(), js.dump(2) + "\n");
  return 0;
}

}  // namespace sl::app
