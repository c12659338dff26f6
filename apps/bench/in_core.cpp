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

// A method's figures over the path. Times and depth complexity of the rasterization frames;
// `median_norast_ms` of the frames that reused their lists.
struct Summary {
  double median_ms = 0, p95_ms = 0, median_norast_ms = 0, median_raycast_ms = 0, median_lists_ms = 0;
  std::uint64_t samples = 0, useful = 0, misses = 0;
  double dc_avg = 0;
  std::uint32_t dc_max = 0;
  double speedup = 0;     // over the median of method none (0 without it)
  double efficiency = 0;  // useful samples over samples
};

// The JSON: an object per method.
using SummaryField = Column<Summary>;
constexpr SummaryField kInCoreSummaryFields[] = {
    SummaryField::field<&Summary::median_ms>("median_ms"),
    SummaryField::field<&Summary::p95_ms>("p95_ms"),
    SummaryField::field<&Summary::median_norast_ms>("median_ms_without_rasterization"),
    SummaryField::field<&Summary::median_raycast_ms>("median_raycast_ms"),
    SummaryField::field<&Summary::median_lists_ms>("median_lists_ms"),
    SummaryField::field<&Summary::speedup>("speedup_vs_none"),
    SummaryField::field<&Summary::samples>("samples"),
    SummaryField::field<&Summary::useful>("useful_samples"),
    SummaryField::field<&Summary::efficiency>("sample_efficiency"),
    SummaryField::field<&Summary::misses>("occupancy_misses"),
    SummaryField::field<&Summary::dc_avg>("depth_complexity_avg"),
    {"depth_complexity_max", [](const auto& s) -> Cell { return std::uint64_t(s.dc_max); }},
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

Summary summarize(const std::vector<FrameRecord>& recs) {
  Summary s;
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
    s.useful += r.stats.useful_samples;
    s.misses += r.stats.occupancy_misses;
    dc += r.stats.depth_complexity_avg;
    s.dc_max = std::max(s.dc_max, r.stats.depth_complexity_max);
    ++n;
  }
  s.median_ms = percentile(total, 0.5);
  s.p95_ms = percentile(total, 0.95);
  s.median_norast_ms = percentile(norast, 0.5);
  s.median_raycast_ms = percentile(raycast, 0.5);
  s.median_lists_ms = percentile(lists, 0.5);
  s.dc_avg = n ? dc / n : 0.0;
  s.efficiency = s.samples ? double(s.useful) / double(s.samples) : 0.0;
  return s;
}

// The median of method none (0 when it was not run); speed-ups are relative to it.
double none_median_ms(const BenchRun& b, const std::vector<Summary>& sums) {
  double none_median = 0;
  for (std::size_t mi = 0; mi < b.methods.size(); ++mi) {
    if (b.methods[mi] == SkipMethod::None) none_median = sums[mi].median_ms;
  }
  return none_median;
}

void print_summary_table(const BenchRun& b, const std::vector<Summary>& sums, double none_median) {
  std::printf("%-11s %10s %10s %12s %9s %13s %11s %10s %8s %6s\n", "method", "median ms", "p95 ms", "w/o rast ms",
              "speed-up", "samples/frame", "efficiency", "lists ms", "dc avg", "dc max");
  for (std::size_t mi = 0; mi < b.methods.size(); ++mi) {
    const Summary& s = sums[mi];
    std::printf("%-11s %10.1f %10.1f %12.1f %9s %13.3g %10.2f%% %10.1f %8.2f %6u\n", to_string(b.methods[mi]),
                s.median_ms, s.p95_ms, s.median_norast_ms,
                none_median > 0 ? (std::to_string(s.speedup).substr(0, 5) + "x").c_str() : "-",
                double(s.samples) / b.path.frames, 100.0 * s.efficiency, s.median_lists_ms, s.dc_avg, s.dc_max);
  }
}

}  // namespace

int bench_in_core(BenchRun& b, std::unique_ptr<SceneRenderer> first) {
  std::printf("bench: %s, %dx%d, %s, %d frames x %zu methods%s\n", b.scene.name.c_str(), b.rs.width, b.rs.height,
              to_string(b.rs.mode), b.path.frames, b.methods.size(),
              b.scene.enabled ? (", " + std::to_string(b.scene.enabled->count()) + " labels enabled").c_str() : "");
  const std::vector<std::vector<FrameRecord>> records = render_in_core(b, std::move(first));
  std::vector<Summary> sums;
  for (const auto& r : records) sums.push_back(summarize(r));
  const double none_median = none_median_ms(b, sums);
  for (Summary& s : sums) s.speedup = none_median > 0 && s.median_ms > 0 ? none_median / s.median_ms : 0.0;
  print_summary_table(b, sums, none_median);
  nlohmann::json js;
  js["volume"] = b.scene.name;
  js["width"] = b.rs.width;
  js["height"] = b.rs.height;
  js["mode"] = to_string(b.rs.mode);
  js["frames"] = b.path.frames;
  for (std::size_t mi = 0; mi < b.methods.size(); ++mi) {
    nlohmann::json method = nlohmann::json::object();
    add_json_fields(method, kInCoreSummaryFields, sums[mi]);
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
