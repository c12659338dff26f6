// `sparseleap bench`: replays a camera path once per method in one process on the same data, records
// per-frame stage times and counters, prints a summary table and writes CSV and JSON.
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>

#include "apps/commands.h"
#include "apps/outputs.h"
#include "apps/render_options.h"
#include "apps/scene_renderer.h"
#include "core/atomic_file.h"
#include "core/camera_path.h"
#include "core/error.h"
#include "core/parallel.h"

namespace sl::app {

namespace {

constexpr const char* kAllMethods = "none,bbox,octree,sparseleap";

struct BenchOptions {
  RenderOptions render;
  std::string path;
  int orbit = 24;
  std::string methods = kAllMethods;
  bool methods_given = false;  // out of core the default is sparseleap
  int warmup = 1;
  bool warmup_given = false;  // out of core the default is 0: a view's cold start is what it measures
  std::string csv, json;
  int max_frames_per_view = 40;
};

struct FrameRecord {
  int frame = 0;
  bool rasterization = true;  // false: lists reused (only the opacity scale changed)
  Stats stats;
};

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const double x = p * double(v.size() - 1);
  const std::size_t i = std::size_t(x);
  const double f = x - double(i);
  return i + 1 < v.size() ? v[i] * (1.0 - f) + v[i + 1] * f : v[i];
}

std::vector<SkipMethod> parse_methods(const std::string& s) {
  std::vector<SkipMethod> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) out.push_back(parse_skip_method(item));
  if (out.empty()) throw InputError("--methods", "no method given");
  return out;
}

struct Summary {
  double median_ms = 0, p95_ms = 0, median_norast_ms = 0, median_raycast_ms = 0, median_lists_ms = 0;
  std::uint64_t samples = 0, useful = 0, misses = 0;
  double dc_avg = 0;
  std::uint32_t dc_max = 0;
};

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
  return s;
}

// Cache hit rate per frame: distinct bricks the rays used that were resident, over those plus the
// distinct bricks they missed.
double hit_rate(const Stats& st) {
  const double all = double(st.cache.hits) + double(st.cache.misses);
  return all > 0.0 ? double(st.cache.hits) / all : 1.0;
}

// Everything a bench run shares, whichever path renders it.
struct BenchRun {
  const BenchOptions& o;
  const CheckedOptions& checked;
  const SourceScene& scene;
  const CameraPath& path;
  const std::vector<SkipMethod>& methods;
  int warmup;
  Backend backend;
  RenderSettings rs;
  OutputFiles& outputs;  // --csv, --json: checked before the run
  const LabelSet* enabled() const { return scene.enabled ? &*scene.enabled : nullptr; }
  std::unique_ptr<SceneRenderer> renderer() const {
    return std::make_unique<SceneRenderer>(scene, o.render, checked, backend);
  }
};

// The CSV and JSON reports (those asked for), as one set: a failing second one removes the first.
void write_reports(BenchRun& b, const std::string& csv, const std::string& json) {
  if (!b.o.csv.empty()) b.outputs.write(b.o.csv, [&](const std::string& p) { write_file_atomic(p, csv); });
  if (!b.o.json.empty()) b.outputs.write(b.o.json, [&](const std::string& p) { write_file_atomic(p, json); });
}

// Out of core: per method, a fresh cache renders every view of the path until it converges (no
// nothing left to load or resolve) or --max-frames-per-view; reports frames to convergence per view,
// loads, completeness, tree and page-table size.
int bench_out_of_core(BenchRun& b, std::unique_ptr<SceneRenderer> first) {
  const BenchOptions& o = b.o;
  const OutOfCoreSettings os = out_of_core_settings(o.render);
  std::printf("bench (out of core): %s, %dx%d, %d views x %zu methods, cache %zu MB, brick %d\n", b.scene.name.c_str(),
              b.rs.width, b.rs.height, b.path.frames, b.methods.size(), os.cache_mb, os.brick);
  nlohmann::json js;
  js["volume"] = b.scene.name;
  std::ostringstream csv;
  csv << "method,view,frame,total_ms,raycast_ms,lists_ms,loads,hits,misses,hit_rate,pending,resident_mb,"
         "tree_nodes,page_table_kb,samples,completeness,lod_coarsened,bricks_missing\n";
  for (std::size_t mi = 0; mi < b.methods.size(); ++mi) {
    const char* method = to_string(b.methods[mi]);
    b.rs.method = b.methods[mi];
    std::unique_ptr<SceneRenderer> renderer = mi == 0 ? std::move(first) : b.renderer();
    for (int w = 0; w < b.warmup; ++w) renderer->render(b.scene.tf, b.enabled(), b.path.at(0), b.rs);
    std::printf("%s\n%5s %9s %12s %10s %11s %10s %12s %11s\n", method, "view", "frames", "converged ms", "loads",
                "resident MB", "tree nodes", "page table KB", "samples");
    nlohmann::json& jm = js["methods"][method];
    jm["views"] = nlohmann::json::array();
    std::vector<double> conv_ms;
    int unconverged = 0;
    std::uint64_t total_loads = 0, total_frames = 0;
    for (int v = 0; v < b.path.frames; ++v) {
      Frame f;
      int n = 0;
      std::uint64_t loads = 0;
      double first_hit_rate = 1.0;
      while (n < o.max_frames_per_view) {
        f = renderer->render(b.scene.tf, b.enabled(), b.path.at(v), b.rs);
        ++n;
        loads += f.stats.cache.loads;
        if (n == 1) first_hit_rate = hit_rate(f.stats);
        csv << method << ',' << v << ',' << n << ',' << f.stats.time_ms.total << ',' << f.stats.time_ms.raycast << ','
            << f.stats.time_ms.lists << ',' << f.stats.cache.loads << ',' << f.stats.cache.hits << ','
            << f.stats.cache.misses << ',' << hit_rate(f.stats) << ',' << f.stats.cache.pending << ','
            << f.stats.cache.resident_mb << ',' << f.stats.tree_nodes << ',' << f.stats.cache.page_table_kb << ','
            << f.stats.samples << ',' << f.stats.cache.completeness << ',' << f.stats.cache.lod_coarsened << ','
            << f.stats.cache.bricks_missing << '\n';
        if (renderer->out_of_core()->converged()) break;
      }
      total_loads += loads;
      total_frames += std::uint64_t(n);
      const bool ok = renderer->out_of_core()->converged();
      unconverged += ok ? 0 : 1;
      if (ok) conv_ms.push_back(f.stats.time_ms.total);
      std::printf("%5d %9s %12.1f %10llu %11.1f %10llu %12.1f %11llu\n", v,
                  ok ? std::to_string(n).c_str() : (">" + std::to_string(n)).c_str(), f.stats.time_ms.total,
                  (unsigned long long)loads, f.stats.cache.resident_mb, (unsigned long long)f.stats.tree_nodes,
                  f.stats.cache.page_table_kb, (unsigned long long)f.stats.samples);
      jm["views"].push_back({{"frames_to_converge", ok ? n : -1}, {"converged_frame_ms", f.stats.time_ms.total},
                             {"loads", loads}, {"resident_mb", f.stats.cache.resident_mb},
                             {"tree_nodes", f.stats.tree_nodes}, {"page_table_kb", f.stats.cache.page_table_kb},
                             {"samples", f.stats.samples}, {"first_frame_hit_rate", first_hit_rate},
                             {"completeness", f.stats.cache.completeness},
                             {"lod_coarsened", f.stats.cache.lod_coarsened},
                             {"bricks_missing", f.stats.cache.bricks_missing}});
    }
    const double per_frame = total_frames ? double(total_loads) / double(total_frames) : 0.0;
    jm["median_converged_frame_ms"] = percentile(conv_ms, 0.5);
    jm["loads_per_frame"] = per_frame;
    jm["unconverged_views"] = unconverged;
    std::printf("%s: median converged frame %.1f ms, %.1f loads per frame, %d views did not converge\n", method,
                percentile(conv_ms, 0.5), per_frame, unconverged);
  }
  write_reports(b, csv.str(), js.dump(2) + "\n");
  return 0;
}

// In core: per method a fresh renderer replays the path; every view is rendered twice, once with its
// lists rebuilt and once with only the opacity scaled (the lists reused: the paper's "w/o
// rasterization").
int bench_in_core(BenchRun& b, std::unique_ptr<SceneRenderer> first) {
  const BenchOptions& o = b.o;
  const TransferFunction dimmer = b.scene.tf.scaled_opacity(0.8f);
  const bool tty = ::isatty(2);
  std::printf("bench: %s, %dx%d, %s, %d frames x %zu methods%s\n", b.scene.name.c_str(), b.rs.width, b.rs.height,
              to_string(b.rs.mode), b.path.frames, b.methods.size(),
              b.scene.enabled ? (", " + std::to_string(b.scene.enabled->count()) + " labels enabled").c_str() : "");
  std::vector<std::vector<FrameRecord>> records(b.methods.size());
  for (std::size_t mi = 0; mi < b.methods.size(); ++mi) {
    b.rs.method = b.methods[mi];
    std::unique_ptr<SceneRenderer> renderer = mi == 0 ? std::move(first) : b.renderer();
    for (int w = 0; w < b.warmup; ++w) renderer->render(b.scene.tf, b.enabled(), b.path.at(0), b.rs);
    for (int f = 0; f < b.path.frames; ++f) {
      renderer->invalidate_lists();  // a rasterization frame always rebuilds its lists
      records[mi].push_back({f, true, renderer->render(b.scene.tf, b.enabled(), b.path.at(f), b.rs).stats});
      // Same view, opacity scaled: the block classes are unchanged, so the lists are reused.
      records[mi].push_back({f, false, renderer->render(dimmer, b.enabled(), b.path.at(f), b.rs).stats});
      if (tty) {
        std::fprintf(stderr, "\r  %-10s frame %d/%d  %.1f ms   ", to_string(b.rs.method), f + 1, b.path.frames,
                     records[mi][records[mi].size() - 2].stats.time_ms.total);
      }
    }
    if (tty) std::fprintf(stderr, "\r%60s\r", "");
  }

  // Summary table.
  std::vector<Summary> sums;
  for (const auto& r : records) sums.push_back(summarize(r));
  double none_median = 0;
  for (std::size_t mi = 0; mi < b.methods.size(); ++mi) {
    if (b.methods[mi] == SkipMethod::None) none_median = sums[mi].median_ms;
  }
  std::printf("%-11s %10s %10s %12s %9s %13s %11s %10s %8s %6s\n", "method", "median ms", "p95 ms", "w/o rast ms",
              "speed-up", "samples/frame", "efficiency", "lists ms", "dc avg", "dc max");
  nlohmann::json js;
  js["volume"] = b.scene.name;
  js["width"] = b.rs.width;
  js["height"] = b.rs.height;
  js["mode"] = to_string(b.rs.mode);
  js["frames"] = b.path.frames;
  for (std::size_t mi = 0; mi < b.methods.size(); ++mi) {
    const Summary& s = sums[mi];
    const double speedup = none_median > 0 && s.median_ms > 0 ? none_median / s.median_ms : 0.0;
    const double eff = s.samples ? double(s.useful) / double(s.samples) : 0.0;
    std::printf("%-11s %10.1f %10.1f %12.1f %9s %13.3g %10.2f%% %10.1f %8.2f %6u\n", to_string(b.methods[mi]),
                s.median_ms, s.p95_ms, s.median_norast_ms,
                none_median > 0 ? (std::to_string(speedup).substr(0, 5) + "x").c_str() : "-",
                double(s.samples) / b.path.frames, 100.0 * eff, s.median_lists_ms, s.dc_avg, s.dc_max);
    js["methods"][to_string(b.methods[mi])] = {{"median_ms", s.median_ms},
                                               {"p95_ms", s.p95_ms},
                                               {"median_ms_without_rasterization", s.median_norast_ms},
                                               {"median_raycast_ms", s.median_raycast_ms},
                                               {"median_lists_ms", s.median_lists_ms},
                                               {"speedup_vs_none", speedup},
                                               {"samples", s.samples},
                                               {"useful_samples", s.useful},
                                               {"sample_efficiency", eff},
                                               {"occupancy_misses", s.misses},
                                               {"depth_complexity_avg", s.dc_avg},
                                               {"depth_complexity_max", s.dc_max}};
  }
  std::ostringstream csv;
  if (!o.csv.empty()) {
    csv << "method,frame,rasterization,total_ms,metadata_ms,tree_ms,geometry_ms,order_ms,lists_ms,raycast_ms,"
           "samples,useful_samples,depth_complexity_avg,depth_complexity_max,boxes,events,occupancy_misses\n";
    for (std::size_t mi = 0; mi < b.methods.size(); ++mi) {
      for (const FrameRecord& r : records[mi]) {
        const Stats& s = r.stats;
        csv << to_string(b.methods[mi]) << ',' << r.frame << ',' << (r.rasterization ? 1 : 0) << ','
            << s.time_ms.total << ',' << s.time_ms.metadata << ',' << s.time_ms.tree << ',' << s.time_ms.geometry
            << ',' << s.time_ms.order << ',' << s.time_ms.lists << ',' << s.time_ms.raycast << ',' << s.samples
            << ',' << s.useful_samples << ',' << s.depth_complexity_avg << ',' << s.depth_complexity_max << ','
            << s.boxes << ',' << s.events << ',' << s.occupancy_misses << '\n';
      }
    }
  }
  write_reports(b, csv.str(), js.dump(2) + "\n");
  return 0;
}

int run_bench(const BenchOptions& o) {
  const RenderOptions& ro = o.render;
  const CheckedOptions checked = check_render_options(ro);
  const bool ooc = ro.out_of_core();
  const std::vector<SkipMethod> methods = parse_methods(ooc && !o.methods_given ? "sparseleap" : o.methods);
  if (ooc) {
    for (SkipMethod m : methods) {
      if (!out_of_core_method(m)) throw InputError("--methods", "out-of-core rendering supports sparseleap and none");
    }
  }
  if (o.warmup < 0 || o.warmup > 100) throw InputError("--warmup", "must be between 0 and 100");
  if (o.path.empty() && (o.orbit < 1 || o.orbit > 100000)) throw InputError("--orbit", "must be between 1 and 100000");
  if (o.max_frames_per_view < 1 || o.max_frames_per_view > 100000) {
    throw InputError("--max-frames-per-view", "must be between 1 and 100000");
  }
  OutputFiles outputs;
  if (!o.csv.empty()) outputs.add(o.csv);
  if (!o.json.empty()) outputs.add(o.json);
  const ThreadLimit threads(ro.threads);

  const SourceScene scene = load_source_scene(ro.scene, ooc);
  RenderSettings rs = checked.settings;
  complete_settings(ro, scene, rs);
  const CameraPath path = o.path.empty() ? orbit_path(scene.desc.extent(), o.orbit) : load_camera_path(o.path);
  std::string notice;  // printed once the first renderer accepted the settings: bad input stays one line
  const Backend backend = choose_backend(ro.backend, &notice);
  BenchRun b{o, checked, scene, path, methods, ooc && !o.warmup_given ? 0 : o.warmup, backend, rs, outputs};
  b.rs.method = methods[0];
  std::unique_ptr<SceneRenderer> first = b.renderer();
  if (!notice.empty()) std::fputs(notice.c_str(), stderr);
  return ooc ? bench_out_of_core(b, std::move(first)) : bench_in_core(b, std::move(first));
}

}  // namespace

Runner add_bench_command(CLI::App& app) {
  auto o = std::make_shared<BenchOptions>();
  CLI::App* c = app.add_subcommand("bench", "Replay a camera path once per method; summary table, CSV and JSON");
  o->render.size = "512x512";
  o->render.backend = "cpu";
  add_render_options(*c, o->render, Command::Bench);
  c->add_option("--path", o->path, "Camera path JSON (keyframes); default: an orbit");
  c->add_option("--orbit", o->orbit, "Frames of the generated orbit")->capture_default_str();
  CLI::Option* methods =
      c->add_option("--methods", o->methods, "Comma-separated methods (out of core: sparseleap and none; default there sparseleap)")
          ->capture_default_str();
  CLI::Option* warmup =
      c->add_option("--warmup", o->warmup, "Unrecorded frames of the first view before each method (out of core: default 0)")
          ->capture_default_str();
  c->add_option("--csv", o->csv, "Per-frame CSV (a row per method and frame; out of core per method, view and frame)");
  c->add_option("--json", o->json, "Summary JSON");
  c->add_option("--max-frames-per-view", o->max_frames_per_view, "Out of core: frames per view at most")
      ->capture_default_str();
  return [o, methods, warmup] {
    o->methods_given = methods->count() > 0;
    o->warmup_given = warmup->count() > 0;
    return run_bench(*o);
  };
}

}  // namespace sl::app
