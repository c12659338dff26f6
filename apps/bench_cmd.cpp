// `sparseleap bench`: replays a camera path once per method in one process on the same data, records
// per-frame stage times and counters, prints a summary table and writes CSV and JSON.
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>

#include <tbb/global_control.h>

#include <optional>

#include "apps/backend.h"
#include "cache/out_of_core.h"
#include "cache/synthetic/procedural_neurites.h"
#include "cache/volume_source.h"
#include "apps/commands.h"
#include "apps/scene_loader.h"
#include "core/atomic_file.h"
#include "core/camera_path.h"
#include "core/error.h"
#include "core/image.h"

namespace sl::app {

namespace {

struct BenchOptions {
  SceneOptions scene;
  std::string path;
  int orbit = 24;
  std::string methods = "none,bbox,octree,sparseleap";
  std::string size = "512x512";
  std::string mode = "dvr";
  std::string backend = "cpu";
  std::string lists = "cpu";
  std::string csv, json;
  float step = 0.5f;
  float iso = NAN;
  int block = 16;
  int warmup = 1;
  int threads = 0;
  bool ert = false;
  // Out of core.
  std::size_t cache_mb = 0;
  int brick = 32;
  float lod_bias = 1.0f;
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

// Out of core: every view of the path is rendered until it converges (no misses, nothing pending) or
// --max-frames-per-view; reports frames to convergence per view, loads, tree and page-table size.
int run_bench_out_of_core(const BenchOptions& o, RenderSettings rs) {
  SourceScene ss = load_source_scene(o.scene, true);
  const std::shared_ptr<const VolumeSource>& source = ss.source;
  const TransferFunction& tf = ss.tf;
  const std::optional<LabelSet>& enabled = ss.enabled;
  const std::string& name = ss.name;
  rs.iso = std::isnan(o.iso) ? 128.0f : o.iso;
  rs.method = SkipMethod::SparseLeap;
  CameraPath path = o.path.empty() ? orbit_path(source->desc().extent(), o.orbit) : load_camera_path(o.path);
  OutOfCoreSettings os;
  os.cache_mb = o.cache_mb > 0 ? o.cache_mb : 1024;
  os.brick = o.brick;
  os.lod_bias = o.lod_bias;
  const ListSource lists = parse_list_source(o.lists);
  std::string notice;
  const Backend backend = choose_backend(o.backend, &notice);
  OutOfCoreRenderer renderer(source, os, rs.block, make_cast_device(backend));
  if (lists == ListSource::Gl) renderer.set_list_builder(make_gl_list_builder());
  if (!notice.empty()) std::fputs(notice.c_str(), stderr);
  std::printf("bench (out of core): %s, %dx%d, %d views, cache %zu MB, brick %d\n", name.c_str(), rs.width,
              rs.height, path.frames, os.cache_mb, os.brick);
  std::printf("%5s %9s %12s %10s %11s %10s %12s %11s\n", "view", "frames", "converged ms", "loads", "resident MB",
              "tree nodes", "page table KB", "samples");
  nlohmann::json js;
  js["volume"] = name;
  js["views"] = nlohmann::json::array();
  std::ostringstream csv;
  // Cache hit rate per frame: distinct bricks the rays used that were resident, over those plus the
  // distinct bricks they missed.
  const auto hit_rate = [](const Stats& st) {
    const double all = double(st.cache.hits) + double(st.cache.misses);
    return all > 0.0 ? double(st.cache.hits) / all : 1.0;
  };
  csv << "view,frame,total_ms,raycast_ms,lists_ms,loads,hits,misses,hit_rate,pending,resident_mb,tree_nodes,"
         "page_table_kb,samples\n";
  std::vector<double> conv_ms;
  int unconverged = 0;
  std::uint64_t total_loads = 0, total_frames = 0;
  for (int v = 0; v < path.frames; ++v) {
    const OutOfCoreScene scene{&tf, enabled ? &*enabled : nullptr, path.at(v)};
    Frame f;
    int n = 0;
    std::uint64_t loads = 0;
    double first_hit_rate = 1.0;
    while (n < o.max_frames_per_view) {
      f = renderer.render(scene, rs);
      ++n;
      loads += f.stats.cache.loads;
      if (n == 1) first_hit_rate = hit_rate(f.stats);
      csv << v << ',' << n << ',' << f.stats.time_ms.total << ',' << f.stats.time_ms.raycast << ','
          << f.stats.time_ms.lists << ',' << f.stats.cache.loads << ',' << f.stats.cache.hits << ','
          << f.stats.cache.misses << ',' << hit_rate(f.stats) << ',' << f.stats.cache.pending << ',' << f.stats.cache.resident_mb << ',' << f.stats.tree_nodes << ','
          << f.stats.cache.page_table_kb << ',' << f.stats.samples << '\n';
      if (renderer.converged()) break;
    }
    total_loads += loads;
    total_frames += std::uint64_t(n);
    const bool ok = renderer.converged();
    unconverged += ok ? 0 : 1;
    if (ok) conv_ms.push_back(f.stats.time_ms.total);
    std::printf("%5d %9s %12.1f %10llu %11.1f %10llu %12.1f %11llu\n", v,
                ok ? std::to_string(n).c_str() : (">" + std::to_string(n)).c_str(), f.stats.time_ms.total,
                (unsigned long long)loads, f.stats.cache.resident_mb, (unsigned long long)f.stats.tree_nodes,
                f.stats.cache.page_table_kb, (unsigned long long)f.stats.samples);
    js["views"].push_back({{"frames_to_converge", ok ? n : -1}, {"converged_frame_ms", f.stats.time_ms.total},
                           {"loads", loads}, {"resident_mb", f.stats.cache.resident_mb},
                           {"tree_nodes", f.stats.tree_nodes}, {"page_table_kb", f.stats.cache.page_table_kb},
                           {"samples", f.stats.samples}, {"first_frame_hit_rate", first_hit_rate}});
  }
  js["median_converged_frame_ms"] = percentile(conv_ms, 0.5);
  js["loads_per_frame"] = total_frames ? double(total_loads) / double(total_frames) : 0.0;
  js["unconverged_views"] = unconverged;
  std::printf("median converged frame %.1f ms, %.1f loads per frame, %d views did not converge\n",
              percentile(conv_ms, 0.5), total_frames ? double(total_loads) / double(total_frames) : 0.0, unconverged);
  if (!o.csv.empty()) write_file_atomic(o.csv, csv.str());
  if (!o.json.empty()) write_file_atomic(o.json, js.dump(2) + "\n");
  return 0;
}

int run_bench(const BenchOptions& o) {
  RenderSettings rs = make_render_settings(o.size, o.mode, "sparseleap", "image", o.step, o.ert, o.block, false);
  const std::vector<SkipMethod> methods = parse_methods(o.methods);
  if (o.warmup < 0 || o.warmup > 100) throw InputError("--warmup", "must be between 0 and 100");
  if (!o.csv.empty()) check_output_prefix(o.csv);
  if (!o.json.empty()) check_output_prefix(o.json);
  std::unique_ptr<tbb::global_control> threads;
  if (o.threads > 0) {
    threads = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, o.threads);
  }

  if (is_procedural_spec(o.scene.volume) || o.cache_mb > 0) return run_bench_out_of_core(o, rs);
  LoadedScene ls = load_scene(o.scene);
  rs.iso = std::isnan(o.iso) ? (ls.volume.type() == VoxelType::U8 ? 128.0f : 0.5f * (ls.tf.vmin() + ls.tf.vmax())) : o.iso;
  CameraPath path;
  if (!o.path.empty()) {
    path = load_camera_path(o.path);
  } else {
    if (o.orbit < 1 || o.orbit > 100000) throw InputError("--orbit", "must be between 1 and 100000");
    path = orbit_path(ls.volume.desc().extent(), o.orbit);
  }
  const TransferFunction dimmer = ls.tf.scaled_opacity(0.8f);  // "w/o rasterization" frames
  Scene scene;
  scene.volume = &ls.volume;
  scene.labels = ls.labels.empty() ? nullptr : &ls.labels;
  scene.tf = &ls.tf;
  scene.enabled = ls.enabled ? &*ls.enabled : nullptr;
  scene.camera = path.at(0);
  validate(scene, rs);
  const ListSource lists = parse_list_source(o.lists);
  const Backend backend = choose_backend(o.backend);

  const bool tty = ::isatty(2);
  std::printf("bench: %s, %dx%d, %s, %d frames x %zu methods%s\n", ls.name.c_str(), rs.width, rs.height,
              to_string(rs.mode), path.frames, methods.size(),
              ls.enabled ? (", " + std::to_string(ls.enabled->count()) + " labels enabled").c_str() : "");
  std::vector<std::vector<FrameRecord>> records(methods.size());
  for (std::size_t mi = 0; mi < methods.size(); ++mi) {
    rs.method = methods[mi];
    FrameRenderer renderer(backend, lists);
    scene.camera = path.at(0);
    scene.tf = &ls.tf;
    for (int w = 0; w < o.warmup; ++w) renderer.render(scene, rs);
    for (int f = 0; f < path.frames; ++f) {
      scene.camera = path.at(f);
      scene.tf = &ls.tf;
      renderer.invalidate_lists();  // a rasterization frame always rebuilds its lists
      records[mi].push_back({f, true, renderer.render(scene, rs).stats});
      // Same view, opacity scaled: the block classes are unchanged, so the lists are reused.
      scene.tf = &dimmer;
      records[mi].push_back({f, false, renderer.render(scene, rs).stats});
      if (tty) {
        std::fprintf(stderr, "\r  %-10s frame %d/%d  %.1f ms   ", to_string(rs.method), f + 1, path.frames,
                     records[mi][records[mi].size() - 2].stats.time_ms.total);
      }
    }
    if (tty) std::fprintf(stderr, "\r%60s\r", "");
  }

  // Summary table.
  std::vector<Summary> sums;
  for (const auto& r : records) sums.push_back(summarize(r));
  double none_median = 0;
  for (std::size_t mi = 0; mi < methods.size(); ++mi) {
    if (methods[mi] == SkipMethod::None) none_median = sums[mi].median_ms;
  }
  std::printf("%-11s %10s %10s %12s %9s %13s %11s %10s %8s %6s\n", "method", "median ms", "p95 ms", "w/o rast ms",
              "speed-up", "samples/frame", "efficiency", "lists ms", "dc avg", "dc max");
  nlohmann::json js;
  js["volume"] = ls.name;
  js["width"] = rs.width;
  js["height"] = rs.height;
  js["mode"] = to_string(rs.mode);
  js["frames"] = path.frames;
  for (std::size_t mi = 0; mi < methods.size(); ++mi) {
    const Summary& s = sums[mi];
    const double speedup = none_median > 0 && s.median_ms > 0 ? none_median / s.median_ms : 0.0;
    const double eff = s.samples ? double(s.useful) / double(s.samples) : 0.0;
    std::printf("%-11s %10.1f %10.1f %12.1f %9s %13.3g %10.2f%% %10.1f %8.2f %6u\n", to_string(methods[mi]),
                s.median_ms, s.p95_ms, s.median_norast_ms,
                none_median > 0 ? (std::to_string(speedup).substr(0, 5) + "x").c_str() : "-",
                double(s.samples) / path.frames, 100.0 * eff, s.median_lists_ms, s.dc_avg, s.dc_max);
    js["methods"][to_string(methods[mi])] = {{"median_ms", s.median_ms},
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
  if (!o.csv.empty()) {
    std::ostringstream csv;
    csv << "method,frame,rasterization,total_ms,metadata_ms,tree_ms,geometry_ms,order_ms,lists_ms,raycast_ms,"
           "samples,useful_samples,depth_complexity_avg,depth_complexity_max,boxes,events,occupancy_misses\n";
    for (std::size_t mi = 0; mi < methods.size(); ++mi) {
      for (const FrameRecord& r : records[mi]) {
        const Stats& s = r.stats;
        csv << to_string(methods[mi]) << ',' << r.frame << ',' << (r.rasterization ? 1 : 0) << ','
            << s.time_ms.total << ',' << s.time_ms.metadata << ',' << s.time_ms.tree << ',' << s.time_ms.geometry
            << ',' << s.time_ms.order << ',' << s.time_ms.lists << ',' << s.time_ms.raycast << ',' << s.samples
            << ',' << s.useful_samples << ',' << s.depth_complexity_avg << ',' << s.depth_complexity_max << ','
            << s.boxes << ',' << s.events << ',' << s.occupancy_misses << '\n';
      }
    }
    write_file_atomic(o.csv, csv.str());
  }
  if (!o.json.empty()) write_file_atomic(o.json, js.dump(2) + "\n");
  return 0;
}

}  // namespace

Runner add_bench_command(CLI::App& app) {
  auto o = std::make_shared<BenchOptions>();
  CLI::App* c = app.add_subcommand("bench", "Replay a camera path once per method; summary table, CSV and JSON");
  add_scene_options(*c, o->scene, false);
  c->add_option("--path", o->path, "Camera path JSON (keyframes); default: an orbit");
  c->add_option("--orbit", o->orbit, "Frames of the generated orbit")->capture_default_str();
  c->add_option("--methods", o->methods, "Comma-separated methods")->capture_default_str();
  c->add_option("--size", o->size, "Image size WxH")->capture_default_str();
  c->add_option("--mode", o->mode, "dvr, mip, iso or labels")->capture_default_str();
  c->add_option("--iso", o->iso, "Iso value (iso mode)");
  c->add_option("--step", o->step, "Sample distance in units of the smallest spacing")->capture_default_str();
  c->add_option("--block", o->block, "Culling block edge in voxels: 4, 8, 16 or 32")->capture_default_str();
  c->add_flag("--ert", o->ert, "Early ray termination");
  c->add_option("--warmup", o->warmup, "Unrecorded frames before each method")->capture_default_str();
  c->add_option("--backend", o->backend, "auto, cpu or cuda")->capture_default_str();
  c->add_option("--lists", o->lists, "Segment-list builder: cpu or gl (OpenGL, headless EGL)")->capture_default_str();
  c->add_option("--threads", o->threads, "CPU threads (0 = all)")->capture_default_str();
  c->add_option("--csv", o->csv, "Per-frame CSV (a row per method and frame)");
  c->add_option("--cache-mb", o->cache_mb, "Out of core with this cache budget (sparseleap only; default for procedural 1024)");
  c->add_option("--brick", o->brick, "Brick payload edge (out of core)")->capture_default_str();
  c->add_option("--lod-bias", o->lod_bias, "Level-of-detail bias (out of core)")->capture_default_str();
  c->add_option("--max-frames-per-view", o->max_frames_per_view, "Out of core: frames per view at most")
      ->capture_default_str();
  c->add_option("--json", o->json, "Summary JSON");
  return [o] { return run_bench(*o); };
}

}  // namespace sl::app
