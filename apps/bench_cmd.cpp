// `sparseleap bench`: replays a camera path once per method in one process on the same data, records
// per-frame stage times and counters, prints a summary table and writes CSV and JSON.
#include <cstdio>
#include <memory>
#include <sstream>

#include "apps/bench/bench_run.h"
#include "apps/bench/loader.h"
#include "apps/commands.h"
#include "apps/render_options.h"
#include "cache/stores/counting_byte_store.h"
#include "core/scene/camera_path.h"
#include "core/util/error.h"
#include "core/util/parallel.h"
#if SL_HAVE_MPI
#include "apps/distributed.h"
#endif

namespace sl::app {

namespace {

CameraPath generated_path(const std::string& kind, const vec3& extent, int frames) {
  if (kind == "orbit") return orbit_path(extent, frames);
  if (kind == "orbit-zoom") return orbit_zoom_path(extent, frames);
  if (kind == "zoom-in") return zoom_in_path(extent, frames);
  throw InputError("--path-kind", "expected orbit, orbit-zoom or zoom-in, not '" + kind + "'");
}

std::vector<SkipMethod> parse_methods(const std::string& s) {
  std::vector<SkipMethod> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) out.push_back(parse_skip_method(item));
  if (out.empty()) throw InputError("--methods", "no method given");
  return out;
}

// Every option is checked before the (possibly slow) data load, so a typo fails at once.
std::vector<SkipMethod> checked_methods(const BenchOptions& o, bool ooc) {
  const std::vector<SkipMethod> methods = parse_methods(ooc && !o.methods_given ? "sparseleap" : o.methods);
  if (ooc) {
    for (SkipMethod m : methods) {
      if (!out_of_core_method(m)) throw InputError("--methods", "out-of-core rendering supports sparseleap and none");
    }
  }
  return methods;
}

void check_bench_options(const BenchOptions& o, bool ooc) {
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
}

// What a streamed store cost: requests and bytes over every store the scene read through.
void print_store_io(const SourceScene& scene) {
  std::uint64_t requests = 0, bytes = 0;
  for (const auto& io : scene.store_io) {
    if (io) requests += io->requests(), bytes += io->bytes();
  }
  if (!scene.store_io.empty()) {
    std::printf("store: %llu requests, %.2f MiB read\n", (unsigned long long)requests, double(bytes) / (1024.0 * 1024.0));
  }
}

int bench(const BenchOptions& o, Distributed* dist) {
  const RenderOptions& ro = o.render;
  const CheckedOptions checked = check_render_options(ro);
  const bool ooc = ro.out_of_core();
  const std::vector<SkipMethod> methods = checked_methods(o, ooc);
  check_bench_options(o, ooc);
  OutputFiles outputs;
  if (!o.csv.empty()) outputs.add(o.csv);
  if (!o.json.empty()) outputs.add(o.json);
  const ThreadLimit threads(ro.threads);
  if (o.loader) return bench_loader(o, outputs);

  const SourceScene scene = load_source_scene(ro.scene, ooc, shows_labels(ro));
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
  print_store_io(scene);
  return rc;
}

int run_bench(const BenchOptions& o) {
#if SL_HAVE_MPI
  if (o.render.distributed) return run_distributed([&](Distributed& d) { return bench(o, &d); });
#endif
  return bench(o, nullptr);
}

// A whole number in [lo, hi], checked while parsing (exit 2, as for every malformed value).
CLI::Validator whole_number_in(long long lo, long long hi) {
  return CLI::Validator(
      [lo, hi](const std::string& v) {
        std::size_t end = 0;
        long long x = 0;
        try {
          x = std::stoll(v, &end);
        } catch (const std::exception&) {
          end = 0;
        }
        if (end == 0 || end != v.size() || x < lo || x > hi) {
          return "must be a whole number from " + std::to_string(lo) + " to " + std::to_string(hi) + ", not '" + v + "'";
        }
        return std::string();
      },
      "");  // the help already says the range
}

// --loader reads bricks the way the out-of-core renderer does, so it needs a volume that is rendered
// out of core; checked with the other option errors, before any data is read.
void check_loader_options(const BenchOptions& o) {
  if (!o.loader) return;
  if (o.render.distributed) throw CLI::ValidationError("--loader", "times one process's loader: not with --distributed");
  if (!o.render.out_of_core()) {
    throw CLI::ValidationError("--loader", "reads bricks out of core: add --cache-mb (or give a procedural volume)");
  }
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
  CLI::Option* loader = c->add_flag(
      "--loader",
      o->loader,
      "Time the brick loader instead of rendering: --loader-passes passes, each a fresh loader with --threads "
      "workers (default the renderer's, min(4, cores)) reading --loader-bricks level-0 bricks nearest the centre, "
      "all asked for at once; per pass and their median: bricks/s, MB/s decoded, latency from request to collect "
      "(p50, p95), failures; --json, and --csv a row per pass. Needs a volume read out of core (--cache-mb, or a "
      "procedural one); the path and method options do not apply");
  c->add_option("--loader-bricks", o->loader_bricks,
                "--loader: level-0 bricks per pass, 1 to 10000000 (all of them when the volume has fewer)")
      ->capture_default_str()
      ->check(whole_number_in(1, kMaxLoaderBricks))
      ->needs(loader);
  c->add_option("--loader-passes", o->loader_passes, "--loader: passes, 1 to 100; a streamed volume is reopened for each")
      ->capture_default_str()
      ->check(whole_number_in(1, kMaxLoaderPasses))
      ->needs(loader);
  c->parse_complete_callback([o] { check_loader_options(*o); });
  return [o, methods, warmup, kind] {
    o->methods_given = methods->count() > 0;
    o->warmup_given = warmup->count() > 0;
    o->path_kind_given = kind->count() > 0;
    return run_bench(*o);
  };
}

}  // namespace sl::app
