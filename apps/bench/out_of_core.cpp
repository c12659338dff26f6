// `sparseleap bench` out of core: per method a fresh cache renders every view of the path until it
// converges; a table per method, a CSV row per frame, a JSON object per method with an entry per view.
#include <algorithm>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <sstream>

#include "apps/bench/bench_run.h"
#include "apps/bench/report_columns.h"
#include "core/util/process_memory.h"
#if SL_HAVE_MPI
#include "apps/distributed.h"
#endif

namespace sl::app {

namespace {

// A frame of a view.
struct OutOfCoreFrame {
  const char* method;
  int view;
  int frame;  // 1-based, within the view
  const Stats& stats;
};

// The CSV: a row per method, view and frame. The columns marked per_view are also in
// the view's JSON entry, with the values of the view's last frame.
using FrameColumn = Column<OutOfCoreFrame>;
constexpr bool kPerView = true;
constexpr FrameColumn kOutOfCoreFrameColumns[] = {
    {"method", [](const auto& f) -> Cell { return f.method; }},
    {"view", [](const auto& f) -> Cell { return f.view; }},
    {"frame", [](const auto& f) -> Cell { return f.frame; }},
    FrameColumn::stat("total_ms"), FrameColumn::stat("raycast_ms"), FrameColumn::stat("lists_ms"),
    FrameColumn::stat("loads"), FrameColumn::stat("hits"), FrameColumn::stat("misses"), FrameColumn::stat("hit_rate"),
    FrameColumn::stat("pending"), FrameColumn::stat("resident_mb", kPerView), FrameColumn::stat("tree_nodes", kPerView),
    FrameColumn::stat("tree_bytes", kPerView), FrameColumn::stat("page_table_bytes", kPerView),
    FrameColumn::stat("samples", kPerView), FrameColumn::stat("completeness", kPerView),
    FrameColumn::stat("lod_coarsened", kPerView), FrameColumn::stat("bricks_missing", kPerView),
    FrameColumn::stat("failed", kPerView), FrameColumn::stat("bricks_retried", kPerView),
    FrameColumn::stat("retries", kPerView), FrameColumn::stat("recovered", kPerView),
    FrameColumn::stat("prefetched"), FrameColumn::stat("prefetch_hits"), FrameColumn::stat("stall"),
};

// A view rendered until it converged (nothing left to load or resolve), or cut by
// --max-frames-per-view or --max-frames.
struct ViewResult {
  int frames = 0;
  double ms = 0.0;       // all its frames
  double last_ms = 0.0;  // its last frame
  std::uint64_t loads = 0, stalls = 0, prefetched = 0, prefetch_hits = 0;
  double first_hit_rate = 1.0;
  bool converged = false;
  bool cut = false;  // --max-frames reached before the view converged
};

// The view's JSON entry, beside the per_view columns of its last frame.
using ViewField = Column<ViewResult>;
constexpr ViewField kViewFields[] = {
    {"frames_to_converge", [](const auto& v) -> Cell { return v.converged ? v.frames : -1; }},
    {"ms_to_converge", [](const auto& v) -> Cell { return v.converged ? v.ms : -1.0; }},
    ViewField::field<&ViewResult::last_ms>("converged_frame_ms"),
    ViewField::field<&ViewResult::loads>("loads"),
    ViewField::field<&ViewResult::stalls>("stall_frames"),
    ViewField::field<&ViewResult::prefetched>("prefetched"),
    ViewField::field<&ViewResult::prefetch_hits>("prefetch_hits"),
    ViewField::field<&ViewResult::first_hit_rate>("first_frame_hit_rate"),
};

// One method's pass over the path, with a fresh cache.
struct MethodRun {
  MethodRun(const char* m, const std::vector<int>& rss, std::unique_ptr<SceneRenderer> r)
      : method(m), rss_at(rss), renderer(std::move(r)) {}

  const char* method;
  const std::vector<int>& rss_at;  // --rss-at
  std::unique_ptr<SceneRenderer> renderer;
  Frame last;  // the frame rendered last
  std::uint64_t frames = 0, loads = 0, stall_frames = 0, prefetched = 0, prefetch_hits = 0;
  int views_done = 0, unconverged = 0;
  int stall_run = 0, longest_stall = 0;  // stalled frames in a row, across views
  std::vector<double> conv_ms, to_conv_ms;  // of the converged views: the last frame, all frames
  std::size_t next_rss = 0;                 // the next --rss-at entry
  nlohmann::json rss = nlohmann::json::object(), rss_cache = nlohmann::json::object();
  nlohmann::json views = nlohmann::json::array();

  double total_to_converge_ms() const {
    double sum = 0;
    for (double x : to_conv_ms) sum += x;
    return sum;
  }
  double loads_per_frame() const { return frames ? double(loads) / double(frames) : 0.0; }
};

// The JSON: an object per method (with the RSS samples and the views beside these).
using MethodField = Column<MethodRun>;
constexpr MethodField kOutOfCoreMethodFields[] = {
    {"median_converged_frame_ms", [](const auto& m) -> Cell { return percentile(m.conv_ms, 0.5); }},
    {"median_ms_to_converge", [](const auto& m) -> Cell { return percentile(m.to_conv_ms, 0.5); }},
    {"total_ms_to_converge", [](const auto& m) -> Cell { return m.total_to_converge_ms(); }},
    MethodField::field<&MethodRun::frames>("frames"),
    MethodField::field<&MethodRun::views_done>("views_rendered"),
    {"loads_per_frame", [](const auto& m) -> Cell { return m.loads_per_frame(); }},
    MethodField::field<&MethodRun::unconverged>("unconverged_views"),
    MethodField::field<&MethodRun::stall_frames>("stall_frames"),
    MethodField::field<&MethodRun::longest_stall>("longest_stall_frames"),
    MethodField::field<&MethodRun::prefetched>("prefetched"),
    MethodField::field<&MethodRun::prefetch_hits>("prefetch_hits"),
    {"page_table_bytes", [](const auto& m) -> Cell { return m.last.stats.cache.page_table_bytes; }},
    {"tree_bytes", [](const auto& m) -> Cell { return m.last.stats.tree_bytes; }},
    {"metadata_blocks", [](const auto& m) -> Cell { return m.last.stats.metadata_blocks; }},
    {"metadata_bytes", [](const auto& m) -> Cell { return m.last.stats.metadata_bytes; }},
};

// Warm-up frames wait for their loads (each rank its own: no collective), so what a warm start holds
// does not depend on how the loader threads were scheduled.
void warm_up_out_of_core(const BenchRun& b, SceneRenderer& r) {
  for (int w = 0; w < b.warmup; ++w) {
    b.render(r, b.path.at(0));
    if (OutOfCoreRenderer* ooc = r.out_of_core()) ooc->wait_for_loads();
  }
}

// Adds a rendered frame to its view's and its method's counts.
void count_frame(const Stats& st, ViewResult& view, MethodRun& m) {
  ++view.frames;
  ++m.frames;
  view.ms += st.time_ms.total;
  view.last_ms = st.time_ms.total;
  const CacheStats& c = st.cache;
  view.loads += c.loads;
  view.prefetched += c.prefetched;
  view.prefetch_hits += c.prefetch_hits;
  // A stall: the frame began with its own loads in flight and made none resident. The bench does
  // not wait for the loader, so a single one can be latency; a run of them that does not end is a
  // loader that stopped making progress.
  view.stalls += c.stall ? 1 : 0;
  m.stall_run = c.stall ? m.stall_run + 1 : 0;
  m.longest_stall = std::max(m.longest_stall, m.stall_run);
  if (view.frames == 1) view.first_hit_rate = hit_rate(st);
}

// The process's RSS when the method's frame count reaches an --rss-at entry.
void sample_rss(const Stats& st, MethodRun& m) {
  const CacheStats& c = st.cache;
  while (m.next_rss < m.rss_at.size() && std::uint64_t(m.rss_at[m.next_rss]) == m.frames) {
    const double mb = resident_mb();
    m.rss[std::to_string(m.rss_at[m.next_rss])] = mb;
    m.rss_cache[std::to_string(m.rss_at[m.next_rss])] = c.resident_mb;
    // The brick cache fills up to its budget; what is not the cache must stay flat.
    std::printf("  RSS at frame %d: %.1f MB (brick cache %.1f MB resident; page table %.1f KB, tree %.1f KB, "
                "%llu tree nodes, metadata for %llu blocks in %.1f KB)\n",
                m.rss_at[m.next_rss], mb, c.resident_mb, double(c.page_table_bytes) / 1024.0,
                double(st.tree_bytes) / 1024.0, (unsigned long long)st.tree_nodes,
                (unsigned long long)st.metadata_blocks, double(st.metadata_bytes) / 1024.0);
    ++m.next_rss;
  }
}

bool max_frames_reached(const BenchRun& b, const MethodRun& m) {
  return b.o.max_frames > 0 && m.frames >= std::uint64_t(b.o.max_frames);
}

// Renders view `v` until it converges or a frame limit cuts it, writing a CSV row per frame.
ViewResult render_view(const BenchRun& b, MethodRun& m, int v, std::ostream& csv) {
  const Camera camera = b.path.at(v);
  // The next view extrapolated from the motion so far (as a viewer would: it does not know the path).
  const Camera next = v > 0 ? extrapolate_camera(b.path.at(v - 1), camera) : camera;
  ViewResult view;
  while (view.frames < b.o.max_frames_per_view) {
    m.last = b.render(*m.renderer, camera, v > 0 ? &next : nullptr);
    count_frame(m.last.stats, view, m);
    write_csv_row(csv, kOutOfCoreFrameColumns, OutOfCoreFrame{m.method, v, view.frames, m.last.stats});
    sample_rss(m.last.stats, m);
    if (b.converged(*m.renderer)) break;
    if (max_frames_reached(b, m)) {
      view.cut = true;
      break;
    }
  }
  view.converged = b.converged(*m.renderer);
  return view;
}

// Adds a finished view to its method: totals, its line of the table, its JSON entry.
void finish_view([[maybe_unused]] const BenchRun& b, MethodRun& m, int v, const ViewResult& view) {
  m.loads += view.loads;
  m.stall_frames += view.stalls;
  m.prefetched += view.prefetched;
  m.prefetch_hits += view.prefetch_hits;
  ++m.views_done;
  m.unconverged += view.converged || view.cut ? 0 : 1;
  if (view.converged) {
    m.conv_ms.push_back(view.last_ms);
    m.to_conv_ms.push_back(view.ms);
  }
  const Stats& st = m.last.stats;
  std::printf("%5d %9s %10.1f %12.1f %10llu %11.1f %10.1f %12.1f %11llu%s\n", v,
              view.converged ? std::to_string(view.frames).c_str() : (">" + std::to_string(view.frames)).c_str(),
              view.ms, st.time_ms.total, (unsigned long long)view.loads, st.cache.resident_mb,
              double(st.tree_bytes) / 1024.0, double(st.cache.page_table_bytes) / 1024.0,
              (unsigned long long)st.samples, view.cut ? " (cut by --max-frames)" : "");
  nlohmann::json entry = nlohmann::json::object();
  add_json_fields(entry, kViewFields, view);
  add_json_fields(entry, kOutOfCoreFrameColumns, OutOfCoreFrame{m.method, v, view.frames, st}, true);
  if (view.cut) entry["cut_by_max_frames"] = true;
#if SL_HAVE_MPI
  if (b.dist) entry["distributed"] = nlohmann::json::parse(b.dist->stats_json(st))["distributed"];
#endif
  m.views.push_back(std::move(entry));
}

void print_method_summary([[maybe_unused]] const BenchRun& b, MethodRun& m) {
  std::printf("%s: %llu frames, %d views, median converged frame %.1f ms, to convergence median %.1f ms "
              "(all views %.1f ms), %.1f loads per frame, %d views did not converge, %llu stall frames "
              "(longest run %d), prefetched %llu (hits %llu), page table %.1f KB, tree %.1f KB\n",
              m.method, (unsigned long long)m.frames, m.views_done, percentile(m.conv_ms, 0.5),
              percentile(m.to_conv_ms, 0.5), m.total_to_converge_ms(), m.loads_per_frame(), m.unconverged,
              (unsigned long long)m.stall_frames, m.longest_stall, (unsigned long long)m.prefetched,
              (unsigned long long)m.prefetch_hits, double(m.last.stats.cache.page_table_bytes) / 1024.0,
              double(m.last.stats.tree_bytes) / 1024.0);
  for (; m.next_rss < m.rss_at.size(); ++m.next_rss) {
    std::printf("  RSS at frame %d: not reached (%llu frames)\n", m.rss_at[m.next_rss], (unsigned long long)m.frames);
  }
#if SL_HAVE_MPI
  if (b.dist) std::printf("%s (last frame)\n", b.dist->summary().c_str());
#endif
}

// One method over the path; returns its JSON object.
nlohmann::json run_out_of_core_method(BenchRun& b, std::size_t mi, std::unique_ptr<SceneRenderer>& first,
                                      const std::vector<int>& rss_at, std::ostream& csv) {
  MethodRun m(to_string(b.methods[mi]), rss_at, b.renderer_for(mi, first));
  warm_up_out_of_core(b, *m.renderer);
  std::printf("%s\n%5s %9s %10s %12s %10s %11s %10s %12s %11s\n", m.method, "view", "frames", "to conv ms",
              "converged ms", "loads", "resident MB", "tree KB", "page table KB", "samples");
  for (int v = 0; v < b.path.frames && !max_frames_reached(b, m); ++v) {
    finish_view(b, m, v, render_view(b, m, v, csv));
  }
  print_method_summary(b, m);
  nlohmann::json j = nlohmann::json::object();
  add_json_fields(j, kOutOfCoreMethodFields, m);
  j["rss_mb_at_frame"] = m.rss;
  j["cache_resident_mb_at_frame"] = m.rss_cache;
  j["views"] = std::move(m.views);
  return j;
}

}  // namespace

// Out of core: per method, a fresh cache renders every view of the path until it converges (nothing
// left to load or resolve) or --max-frames-per-view; reports frames and milliseconds to convergence
// per view, loads, stalls (frames with loads pending and none made), completeness, prefetch, tree and
// page-table size, and the process's RSS at the --rss-at frames.
int bench_out_of_core(BenchRun& b, std::unique_ptr<SceneRenderer> first) {
  const OutOfCoreSettings os = out_of_core_settings(b.o.render);
  const std::vector<int> rss_at = parse_frame_list(b.o.rss_at);
  std::printf("bench (out of core): %s, %dx%d, %d views x %zu methods, cache %zu MB, brick %d, prefetch %s\n",
              b.scene.name.c_str(), b.rs.width, b.rs.height, b.path.frames, b.methods.size(), os.cache_mb, os.brick,
              os.prefetch ? "on" : "off");
  nlohmann::json js;
  js["volume"] = b.scene.name;
  js["prefetch"] = os.prefetch;
  std::ostringstream csv;
  write_csv_header(csv, kOutOfCoreFrameColumns);
  for (std::size_t mi = 0; mi < b.methods.size(); ++mi) {
    js["methods"][to_string(b.methods[mi])] = run_out_of_core_method(b, mi, first, rss_at, csv);
  }
  write_reports(b, csv.str(), js.dump(2) + "\n");
  return 0;
}

}  // namespace sl::app
