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
#include "cache/stores/counting_byte_store.h"
#include "core/util/atomic_file.h"
#include "core/scene/camera_path.h"
#include "core/util/error.h"
#include "core/util/parallel.h"
#include "core/util/process_memory.h"
#if SL_HAVE_MPI
#include "apps/distributed.h"
#endif

namespace sl::app {

class Distributed;  // apps/distributed.h (SL_MPI builds)

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
  std::string path_kind = "orbit";  // generated path: orbit, orbit-zoom, zoom-in
  bool path_kind_given = false;
  std::string rss_at;               // out of core: frame numbers (1-based, per method) to report RSS at
  int max_frames = 0;               // out of core: frames per method at most (0: the whole path)
};

// `--rss-at 100,1000,2000`: ascending frame numbers >= 1.
std::vector<int> parse_frame_list(const std::string& s) {
  std::vector<int> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) {
    std::size_t end = 0;
    int v = 0;
    try {
      v = std::stoi(item, &end);
    } catch (const std::exception&) {
      end = 0;
    }
    if (end == 0 || end != item.size() || v < 1) throw InputError("--rss-at", "expected frame numbers >= 1, e.g. 100,1000,2000");
    out.push_back(v);
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

CameraPath generated_path(const std::string& kind, const vec3& extent, int frames) {
  if (kind == "orbit") return orbit_path(extent, frames);
  if (kind == "orbit-zoom") return orbit_zoom_path(extent, frames);
  if (kind == "zoom-in") return zoom_in_path(extent, frames);
  throw InputError("--path-kind", "expected orbit, orbit-zoom or zoom-in, not '" + kind + "'");
}

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
  Distributed* dist = nullptr;  // --distributed: this rank's share of the job
  const LabelSet* enabled() const { return scene.enabled ? &*scene.enabled : nullptr; }
  std::unique_ptr<SceneRenderer> renderer() const {
    auto r = std::make_unique<SceneRenderer>(scene, o.render, checked, backend);
#if SL_HAVE_MPI
    if (dist) {
      const CullParams cull{rs.mode, &scene.tf, rs.iso, enabled()};
      OutOfCoreRenderer& ooc = *r->out_of_core();
      ooc.set_sample_clip(dist->balance(*scene.source, ooc.layout(), rs.block, cull).clip);
    }
#endif
    return r;
  }
  // One frame of `camera`: distributed, every rank's region composited (rank 0 holds the image).
  // `next`: the view expected next (prefetch along the motion).
  Frame render(SceneRenderer& r, const Camera& camera, const Camera* next = nullptr) const {
    Frame f = r.render(scene.tf, enabled(), camera, rs, next);
#if SL_HAVE_MPI
    if (dist) f = dist->composite(std::move(f), view_point(make_ray_generator(camera, rs.width, rs.height)));
#endif
    return f;
  }
  // Nothing left to load or resolve (distributed: on every rank).
  bool converged(const SceneRenderer& r) const {
    const bool c = r.out_of_core()->converged();
#if SL_HAVE_MPI
    if (dist) return dist->all(c);
#endif
    return c;
  }
};

// The CSV and JSON reports (those asked for), as one set: a failing second one removes the first.
void write_reports(BenchRun& b, const std::string& csv, const std::string& json) {
#if SL_HAVE_MPI
  if (b.dist && !b.dist->root()) return;
#endif
  if (!b.o.csv.empty()) b.outputs.write(b.o.csv, [&](const std::string& p) { write_file_atomic(p, csv); });
  if (!b.o.json.empty()) b.outputs.write(b.o.json, [&](const std::string& p) { write_file_atomic(p, json); });
}

// Out of core: per method, a fresh cache renders every view of the path until it converges (nothing
// left to load or resolve) or --max-frames-per-view; reports frames and milliseconds to convergence
// per view, loads, stalls (frames with loads pending and none made), completeness, prefetch, tree and
// page-table size, and the process's RSS at the --rss-at frames.
int bench_out_of_core(BenchRun& b, std::unique_ptr<SceneRenderer> first) {
  const BenchOptions& o = b.o;
  const OutOfCoreSettings os = out_of_core_settings(o.render);
  const std::vector<int> rss_at = parse_frame_list(o.rss_at);
  std::printf("bench (out of core): %s, %dx%d, %d views x %zu methods, cache %zu MB, brick %d, prefetch %s\n",
              b.scene.name.c_str(), b.rs.width, b.rs.height, b.path.frames, b.methods.size(), os.cache_mb, os.brick,
              os.prefetch ? "on" : "off");
  nlohmann::json js;
  js["volume"] = b.scene.name;
  js["prefetch"] = os.prefetch;
  std::ostringstream csv;
  csv << "method,view,frame,total_ms,raycast_ms,lists_ms,loads,hits,misses,hit_rate,pending,resident_mb,"
         "tree_nodes,tree_bytes,page_table_bytes,samples,completeness,lod_coarsened,bricks_missing,failed,"
         "bricks_retried,retries,recovered,prefetched,prefetch_hits,stall\n";
  for (std::size_t mi = 0; mi < b.methods.size(); ++mi) {
    const char* method = to_string(b.methods[mi]);
    b.rs.method = b.methods[mi];
    std::unique_ptr<SceneRenderer> renderer = mi == 0 ? std::move(first) : b.renderer();
    // Warm-up frames wait for their loads (each rank its own: no collective), so what a warm start
    // holds does not depend on how the loader threads were scheduled.
    for (int w = 0; w < b.warmup; ++w) {
      b.render(*renderer, b.path.at(0));
      if (OutOfCoreRenderer* ooc = renderer->out_of_core()) ooc->wait_for_loads();
    }
    std::printf("%s\n%5s %9s %10s %12s %10s %11s %10s %12s %11s\n", method, "view", "frames", "to conv ms",
                "converged ms", "loads", "resident MB", "tree KB", "page table KB", "samples");
    nlohmann::json& jm = js["methods"][method];
    jm["views"] = nlohmann::json::array();
    std::vector<double> conv_ms, to_conv_ms;
    int unconverged = 0, views_done = 0;
    std::uint64_t total_loads = 0, total_frames = 0, stall_frames = 0, prefetched = 0, prefetch_hits = 0;
    int stall_run = 0, longest_stall = 0;
    std::size_t next_rss = 0;
    nlohmann::json rss = nlohmann::json::object(), rss_cache = nlohmann::json::object();
    Frame f;
    for (int v = 0; v < b.path.frames; ++v) {
      if (o.max_frames > 0 && total_frames >= std::uint64_t(o.max_frames)) break;
      const Camera camera = b.path.at(v);
      // The next view extrapolated from the motion so far (as a viewer would: it does not know the path).
      const Camera next = v > 0 ? extrapolate_camera(b.path.at(v - 1), camera) : camera;
      int n = 0;
      std::uint64_t loads = 0, view_stalls = 0, view_prefetched = 0, view_prefetch_hits = 0;
      double first_hit_rate = 1.0, ms = 0.0;
      bool cut = false;  // --max-frames reached before the view converged
      while (n < o.max_frames_per_view) {
        f = b.render(*renderer, camera, v > 0 ? &next : nullptr);
        ++n;
        ++total_frames;
        ms += f.stats.time_ms.total;
        const CacheStats& c = f.stats.cache;
        loads += c.loads;
        view_prefetched += c.prefetched;
        view_prefetch_hits += c.prefetch_hits;
        // A stall (issue 14's "0 loads with bricks pending"): the frame began with its own loads in
        // flight and made none resident. Without waiting for the loader a single one can be latency;
        // a run of them that does not end is the stall the issue saw.
        const bool stall = c.stall;
        view_stalls += stall ? 1 : 0;
        stall_run = stall ? stall_run + 1 : 0;
        longest_stall = std::max(longest_stall, stall_run);
        if (n == 1) first_hit_rate = hit_rate(f.stats);
        csv << method << ',' << v << ',' << n << ',' << f.stats.time_ms.total << ',' << f.stats.time_ms.raycast << ','
            << f.stats.time_ms.lists << ',' << c.loads << ',' << c.hits << ',' << c.misses << ',' << hit_rate(f.stats)
            << ',' << c.pending << ',' << c.resident_mb << ',' << f.stats.tree_nodes << ',' << f.stats.tree_bytes << ','
            << c.page_table_bytes << ',' << f.stats.samples << ',' << c.completeness << ',' << c.lod_coarsened << ','
            << c.bricks_missing << ',' << c.failed << ',' << c.bricks_retried << ',' << c.retries << ',' << c.recovered
            << ',' << c.prefetched << ',' << c.prefetch_hits << ',' << (stall ? 1 : 0) << '\n';
        while (next_rss < rss_at.size() && std::uint64_t(rss_at[next_rss]) == total_frames) {
          const double mb = resident_mb();
          rss[std::to_string(rss_at[next_rss])] = mb;
          rss_cache[std::to_string(rss_at[next_rss])] = c.resident_mb;
          // The brick cache fills up to its budget; what is not the cache must stay flat.
          std::printf("  RSS at frame %d: %.1f MB (brick cache %.1f MB resident; page table %.1f KB, tree %.1f KB, "
                      "%llu tree nodes, metadata for %llu blocks in %.1f KB)\n",
                      rss_at[next_rss], mb, c.resident_mb, double(c.page_table_bytes) / 1024.0,
                      double(f.stats.tree_bytes) / 1024.0, (unsigned long long)f.stats.tree_nodes,
                      (unsigned long long)f.stats.metadata_blocks, double(f.stats.metadata_bytes) / 1024.0);
          ++next_rss;
        }
        if (b.converged(*renderer)) break;
        if (o.max_frames > 0 && total_frames >= std::uint64_t(o.max_frames)) {
          cut = true;
          break;
        }
      }
      total_loads += loads;
      stall_frames += view_stalls;
      prefetched += view_prefetched;
      prefetch_hits += view_prefetch_hits;
      ++views_done;
      const bool ok = b.converged(*renderer);
      unconverged += ok || cut ? 0 : 1;
      if (ok) {
        conv_ms.push_back(f.stats.time_ms.total);
        to_conv_ms.push_back(ms);
      }
      const CacheStats& c = f.stats.cache;
      std::printf("%5d %9s %10.1f %12.1f %10llu %11.1f %10.1f %12.1f %11llu%s\n", v,
                  ok ? std::to_string(n).c_str() : (">" + std::to_string(n)).c_str(), ms, f.stats.time_ms.total,
                  (unsigned long long)loads, c.resident_mb, double(f.stats.tree_bytes) / 1024.0,
                  double(c.page_table_bytes) / 1024.0, (unsigned long long)f.stats.samples,
                  cut ? " (cut by --max-frames)" : "");
      jm["views"].push_back({{"frames_to_converge", ok ? n : -1}, {"ms_to_converge", ok ? ms : -1.0},
                             {"converged_frame_ms", f.stats.time_ms.total}, {"loads", loads},
                             {"stall_frames", view_stalls}, {"prefetched", view_prefetched},
                             {"prefetch_hits", view_prefetch_hits}, {"resident_mb", c.resident_mb},
                             {"tree_nodes", f.stats.tree_nodes}, {"tree_bytes", f.stats.tree_bytes},
                             {"page_table_bytes", c.page_table_bytes},
                             {"samples", f.stats.samples}, {"first_frame_hit_rate", first_hit_rate},
                             {"completeness", c.completeness},
                             {"lod_coarsened", c.lod_coarsened},
                             {"bricks_missing", c.bricks_missing}, {"failed", c.failed},
                             {"bricks_retried", c.bricks_retried}, {"retries", c.retries},
                             {"recovered", c.recovered}});
      if (cut) jm["views"].back()["cut_by_max_frames"] = true;
#if SL_HAVE_MPI
      if (b.dist) jm["views"].back()["distributed"] = nlohmann::json::parse(b.dist->stats_json(f.stats))["distributed"];
#endif
    }
    double sum_ms = 0;
    for (double x : to_conv_ms) sum_ms += x;
    const double per_frame = total_frames ? double(total_loads) / double(total_frames) : 0.0;
    jm["median_converged_frame_ms"] = percentile(conv_ms, 0.5);
    jm["median_ms_to_converge"] = percentile(to_conv_ms, 0.5);
    jm["total_ms_to_converge"] = sum_ms;
    jm["frames"] = total_frames;
    jm["views_rendered"] = views_done;
    jm["loads_per_frame"] = per_frame;
    jm["unconverged_views"] = unconverged;
    jm["stall_frames"] = stall_frames;
    jm["longest_stall_frames"] = longest_stall;
    jm["prefetched"] = prefetched;
    jm["prefetch_hits"] = prefetch_hits;
    jm["rss_mb_at_frame"] = rss;
    jm["cache_resident_mb_at_frame"] = rss_cache;
    jm["page_table_bytes"] = f.stats.cache.page_table_bytes;
    jm["tree_bytes"] = f.stats.tree_bytes;
    jm["metadata_blocks"] = f.stats.metadata_blocks;
    jm["metadata_bytes"] = f.stats.metadata_bytes;
    std::printf("%s: %llu frames, %d views, median converged frame %.1f ms, to convergence median %.1f ms "
                "(all views %.1f ms), %.1f loads per frame, %d views did not converge, %llu stall frames "
                "(longest run %d), prefetched %llu (hits %llu), page table %.1f KB, tree %.1f KB\n",
                method, (unsigned long long)total_frames, views_done, percentile(conv_ms, 0.5),
                percentile(to_conv_ms, 0.5), sum_ms, per_frame, unconverged, (unsigned long long)stall_frames,
                longest_stall, (unsigned long long)prefetched, (unsigned long long)prefetch_hits,
                double(f.stats.cache.page_table_bytes) / 1024.0, double(f.stats.tree_bytes) / 1024.0);
    for (; next_rss < rss_at.size(); ++next_rss) {
      std::printf("  RSS at frame %d: not reached (%llu frames)\n", rss_at[next_rss], (unsigned long long)total_frames);
    }
#if SL_HAVE_MPI
    if (b.dist) std::printf("%s (last frame)\n", b.dist->summary().c_str());
#endif
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

int bench(const BenchOptions& o, Distributed* dist) {
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
  if (o.max_frames < 0) throw InputError("--max-frames", "must be 0 (no limit) or a number of frames");
  if (!o.path.empty() && o.path_kind_given) throw InputError("--path-kind", "generates a path: not with --path");
  generated_path(o.path_kind, vec3(1.0f), 1);  // checks the kind before any data load
  parse_frame_list(o.rss_at);
  if (!ooc && (!o.rss_at.empty() || o.max_frames > 0)) {
    throw InputError(o.rss_at.empty() ? "--max-frames" : "--rss-at", "out of core only (add --cache-mb)");
  }
  OutputFiles outputs;
  if (!o.csv.empty()) outputs.add(o.csv);
  if (!o.json.empty()) outputs.add(o.json);
  const ThreadLimit threads(ro.threads);

  const SourceScene scene = load_source_scene(ro.scene, ooc);
  RenderSettings rs = checked.settings;
  complete_settings(ro, scene, rs);
  const CameraPath path =
      o.path.empty() ? generated_path(o.path_kind, scene.desc.extent(), o.orbit) : load_camera_path(o.path);
  std::string notice;  // printed once the first renderer accepted the settings: bad input stays one line
  const Backend backend = choose_backend(ro.backend, &notice);
  BenchRun b{o, checked, scene, path, methods, ooc && !o.warmup_given ? 0 : o.warmup, backend, rs, outputs, dist};
  b.rs.method = methods[0];
  std::unique_ptr<SceneRenderer> first = b.renderer();
  if (!notice.empty()) std::fputs(notice.c_str(), stderr);
  const int rc = ooc ? bench_out_of_core(b, std::move(first)) : bench_in_core(b, std::move(first));
  std::uint64_t requests = 0, bytes = 0;
  for (const auto& io : scene.store_io) {
    if (io) requests += io->requests(), bytes += io->bytes();
  }
  if (!scene.store_io.empty()) {
    std::printf("store: %llu requests, %.2f MiB read\n", (unsigned long long)requests, double(bytes) / (1024.0 * 1024.0));
  }
  return rc;
}

int run_bench(const BenchOptions& o) {
#if SL_HAVE_MPI
  if (o.render.distributed) return run_distributed([&](Distributed& d) { return bench(o, &d); });
#endif
  return bench(o, nullptr);
}

}  // namespace

Runner add_bench_command(CLI::App& app) {
  auto o = std::make_shared<BenchOptions>();
  CLI::App* c = app.add_subcommand("bench", "Replay a camera path once per method; summary table, CSV and JSON");
  o->render.size = "512x512";
  o->render.backend = "cpu";
  add_render_options(*c, o->render, Command::Bench);
  c->add_option("--path", o->path, "Camera path JSON (keyframes); default: an orbit");
  c->add_option("--orbit", o->orbit, "Views of the generated path (--path-kind)")->capture_default_str();
  CLI::Option* kind = c->add_option("--path-kind", o->path_kind,
                                    "Generated path: orbit; orbit-zoom (orbit while the distance swings 3 times "
                                    "between the default and a quarter of it, so the level of detail changes); "
                                    "zoom-in (straight towards the centre, to a fifth of the distance)")
                          ->capture_default_str();
  c->add_option("--rss-at", o->rss_at,
                "Out of core: print the process RSS at these frame numbers (counted over all views of a method), "
                "e.g. 100,1000,2000; also in the JSON");
  c->add_option("--max-frames", o->max_frames, "Out of core: frames per method at most (0: every view of the path)")
      ->capture_default_str();
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
  return [o, methods, warmup, kind] {
    o->methods_given = methods->count() > 0;
    o->warmup_given = warmup->count() > 0;
    o->path_kind_given = kind->count() > 0;
    return run_bench(*o);
  };
}

}  // namespace sl::app
