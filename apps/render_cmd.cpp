// `sparseleap render`: one view to PREFIX.png and PREFIX.exr (out of core rendered until complete), a
// one-line summary, optional stats JSON.
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>

#include "apps/commands.h"
#include "apps/outputs.h"
#include "apps/render_options.h"
#include "apps/scene_renderer.h"
#include "cache/stores/store_url.h"
#include "core/util/atomic_file.h"
#include "core/util/error.h"
#include "core/util/parallel.h"
#if SL_HAVE_MPI
#include "apps/distributed.h"
#endif

namespace sl::app {

class Distributed;  // apps/distributed.h (SL_MPI builds)

namespace {

// Exit status of an out-of-core render whose image is incomplete (written, without --allow-partial);
// 1-3 are taken by input, syntax and internal errors (docs/cli.md "Errors, exit status and outputs").
constexpr int kExitPartial = 4;
// The cap on frames of one view without --frames or --max-frames: far above what a settling view
// takes (each frame waits for the loads the last one asked for, so frames follow the tree's growth
// and the per-frame upload budget, not the loader's speed), so reaching it means the view is not
// settling, and a run left alone still ends.
constexpr int kDefaultMaxFrames = 1000;
constexpr int kFrameLimit = 100000;

struct RenderCommandOptions {
  RenderOptions render;
  std::string out = "sparseleap";
  std::string stats_json;
  int frames = 0;  // exactly this many frames; 0 (no --frames): until complete, within the caps below
  int max_frames = kDefaultMaxFrames;
  double time_budget_s = 0;  // 0 (no --time-budget): none
  bool frames_given = false, max_frames_given = false, time_budget_given = false;
  bool allow_partial = false;
  bool strict = false;
};

// Why the frames stopped.
enum class Stop { Complete, Settled, Frames, MaxFrames, TimeBudget };

// The frames of one view: the last frame, how many, how long, and whether every rank converged.
struct FrameRun {
  Frame frame;
  int frames = 0;
  double seconds = 0;
  bool converged = true;  // in core: one frame is the image
  Stop stop = Stop::Complete;
};

// Complete: converged (nothing left to load or resolve) with every sample at its level. In core
// there is no cache stats and one frame is the image.
bool complete(const FrameRun& run) {
  const CacheStats& c = run.frame.stats.cache;
  return !c.present || (run.converged && c.completeness >= 1.0);
}

// A terminal's progress line, redrawn in place.
void print_progress(const FrameRun& run, const OutOfCoreRenderer& r) {
  const CacheStats& c = run.frame.stats.cache;
  std::fprintf(stderr, "\r  frame %d: %5.1f %% complete, %llu bricks pending, %zu resident, %.1f s   ", run.frames,
               100.0 * c.completeness, (unsigned long long)c.pending, r.resident_bricks(), run.seconds);
  std::fflush(stderr);
}

// Renders frames of the one view: exactly --frames, or until complete within --max-frames and
// --time-budget. Out of core a frame never waits for loads, so between frames the loop waits for the
// ones the last frame asked for when it has any in flight: a frame that would only find them still
// loading is a wasted frame, while one with nothing in flight (the tree grows, metadata resolve)
// follows at once. Distributed (`dist`), every rank renders until all ranks are done.
FrameRun render_view(const RenderCommandOptions& o, SceneRenderer& renderer, const SourceScene& scene,
                     const RenderSettings& rs, bool progress, [[maybe_unused]] Distributed* dist) {
  const LabelSet* enabled = scene.enabled ? &*scene.enabled : nullptr;
  const Timer timer;
  FrameRun run;
  for (;;) {
    run.frame = renderer.render(scene.tf, enabled, scene.camera, rs);
    ++run.frames;
    run.seconds = timer.ms() / 1000.0;
    OutOfCoreRenderer* ooc = renderer.out_of_core();
    if (!ooc) {
      if (run.frames >= std::max(o.frames, 1)) return run;
      continue;
    }
    run.converged = ooc->converged();
    bool over_budget = o.time_budget_s > 0 && run.seconds >= o.time_budget_s;
#if SL_HAVE_MPI
    if (dist) {
      run.converged = dist->all(run.converged);
      over_budget = !dist->all(!over_budget);  // the slowest rank's clock decides for all
    }
#endif
    if (progress) print_progress(run, *ooc);
    if (o.frames > 0) {
      if (run.frames >= o.frames) {
        run.stop = complete(run) ? Stop::Complete : run.converged ? Stop::Settled : Stop::Frames;
        break;
      }
    } else if (run.converged) {
      run.stop = complete(run) ? Stop::Complete : Stop::Settled;
      break;
    } else if (run.frames >= o.max_frames) {
      run.stop = Stop::MaxFrames;
      break;
    } else if (over_budget) {
      run.stop = Stop::TimeBudget;
      break;
    }
    if (run.frame.stats.cache.pending > 0) ooc->wait_for_loads();
  }
  if (progress) std::fputc('\n', stderr);
  return run;
}

// What is short in an incomplete frame: samples at their level, bricks missing, loading, failed.
std::string shortfall(const CacheStats& c) {
  char buf[256];
  int n = std::snprintf(buf, sizeof buf, "%.1f %% of samples at their level", 100.0 * c.completeness);
  const auto add = [&](std::uint64_t count, const char* what) {
    if (count == 0 || n >= int(sizeof buf)) return;
    n += std::snprintf(buf + n, sizeof buf - n, ", %llu %s", (unsigned long long)count, what);
  };
  add(c.bricks_missing, "bricks missing");
  add(c.pending, "bricks loading");
  add(c.failed, "bricks failed to load");
  return buf;
}

// Why the frames stopped short and what would help, after "after N frames in S s".
std::string stop_reason(const FrameRun& run, double time_budget_s) {
  const CacheStats& c = run.frame.stats.cache;
  char buf[256];
  switch (run.stop) {
    case Stop::Frames:
      return " (--frames); more --frames, none (render until complete) or --allow-partial";
    case Stop::MaxFrames:
      return " (--max-frames); a larger --max-frames or --cache-mb, or --allow-partial";
    case Stop::TimeBudget:
      std::snprintf(buf, sizeof buf, " (--time-budget %g); a larger --time-budget or --cache-mb, or --allow-partial",
                    time_budget_s);
      return buf;
    case Stop::Settled:
    case Stop::Complete:
      break;
  }
  if (c.working_set_mb > 0) {
    std::snprintf(buf, sizeof buf,
                  "; the view needs about %.1f MB at level %d, the cache has %.1f MB: a larger --cache-mb, a coarser "
                  "--lod or --allow-partial",
                  c.working_set_mb, c.working_set_level, c.cache_mb);
    return buf;
  }
  if (c.failed > 0) return "; bricks that failed to load stay missing (--allow-partial accepts it)";
  return "; more frames do not change it: a larger --cache-mb or --allow-partial";
}

// One line for a complete image coarsened under cache pressure (the image is what the cache holds).
std::string coarsened_note(const CacheStats& c) {
  if (!c.present || c.lod_coarsened <= 0.0) return {};
  char buf[256];
  std::snprintf(buf, sizeof buf, "sparseleap: %.1f %% of samples coarser than the pixel footprint asks",
                100.0 * c.lod_coarsened);
  std::string s = buf;
  if (c.working_set_mb > 0) {
    std::snprintf(buf, sizeof buf, ": the view needs about %.1f MB at level %d; the cache has %.1f MB",
                  c.working_set_mb, c.working_set_level, c.cache_mb);
    s += buf;
  }
  return s;
}

// The exit status of a written image, and its one line on stderr when it is not complete.
int report_completeness(const RenderCommandOptions& o, const FrameRun& run, const std::string& written) {
  const CacheStats& c = run.frame.stats.cache;
  if (o.strict && c.failed > 0) {
    std::fprintf(stderr, "sparseleap: error: %llu bricks failed to load (--strict)\n", (unsigned long long)c.failed);
    return 1;
  }
  if (complete(run)) {
    if (const std::string note = coarsened_note(c); !note.empty()) std::fprintf(stderr, "%s\n", note.c_str());
    return 0;
  }
  std::fprintf(stderr, "sparseleap: %s image written to %s: %s after %d frames in %.1f s%s\n",
               o.allow_partial ? "partial (--allow-partial)" : "incomplete", written.c_str(), shortfall(c).c_str(),
               run.frames, run.seconds, stop_reason(run, o.time_budget_s).c_str());
  return o.allow_partial ? 0 : kExitPartial;
}

void check_frame_options(const RenderCommandOptions& o) {
  if (o.frames_given && (o.frames < 1 || o.frames > kFrameLimit)) {
    throw InputError("--frames", "must be between 1 and 100000");
  }
  if (o.frames_given && (o.max_frames_given || o.time_budget_given)) {
    throw InputError(o.max_frames_given ? "--max-frames" : "--time-budget",
                     "caps rendering until complete; --frames renders exactly N frames instead");
  }
  if (o.max_frames < 1 || o.max_frames > kFrameLimit) throw InputError("--max-frames", "must be between 1 and 100000");
  if (o.time_budget_given && !(o.time_budget_s > 0 && std::isfinite(o.time_budget_s))) {
    throw InputError("--time-budget", "must be a number of seconds greater than 0");
  }
}

// Out of core the volume is read through the page table and brick cache, bricks stream in over the
// frames (a progress line on a terminal); the last frame is written, complete or the best there is.
// Distributed (`dist`), every rank renders its region's frames and the last is composited; rank 0
// writes it.
int render_frames(const RenderCommandOptions& o, [[maybe_unused]] Distributed* dist) {
  const RenderOptions& ro = o.render;
  const CheckedOptions checked = check_render_options(ro);
  const std::string png = output_with_extension(o.out, ".png"), exr = output_with_extension(o.out, ".exr");
  OutputFiles outputs;
  outputs.add(png);
  outputs.add(exr);
  if (!o.stats_json.empty()) outputs.add(o.stats_json);
  check_frame_options(o);
  const ThreadLimit threads(ro.threads);

  const SourceScene scene = load_source_scene(ro.scene, ro.out_of_core(), shows_labels(ro));
  RenderSettings rs = checked.settings;
  complete_settings(ro, scene, rs);
  std::string notice;  // printed once the renderer accepted the settings: bad input stays one line
  const Backend backend = choose_backend(ro.backend, &notice);
  SceneRenderer renderer(scene, ro, checked, backend);
  bool root = true;  // the rank that prints and writes
#if SL_HAVE_MPI
  root = !dist || dist->root();
#endif
  if (!notice.empty() && root) std::fputs(notice.c_str(), stderr);

  const bool progress = scene.out_of_core() && ::isatty(2) && root;
#if SL_HAVE_MPI
  if (dist) {
    const LabelSet* enabled = scene.enabled ? &*scene.enabled : nullptr;
    const CullParams cull{rs.mode, &scene.tf, rs.iso, enabled};
    OutOfCoreRenderer& r = *renderer.out_of_core();
    r.set_sample_clip(dist->balance(*scene.source, r.layout(), rs.block, cull).clip);
  }
#endif
  FrameRun run = render_view(o, renderer, scene, rs, progress, dist);
  Frame& frame = run.frame;
#if SL_HAVE_MPI
  if (dist) {
    frame = dist->composite(std::move(frame), view_point(make_ray_generator(scene.camera, rs.width, rs.height)));
    if (!dist->root()) return 0;
  }
#endif
  outputs.write(png, [&](const std::string& p) { write_png(p, frame.image); });
  outputs.write(exr, [&](const std::string& p) { write_exr(p, frame.image); });
  if (!o.stats_json.empty()) {
    std::string js = stats_to_json(frame.stats);
#if SL_HAVE_MPI
    if (dist) js = dist->stats_json(frame.stats);
#endif
    outputs.write(o.stats_json, [&](const std::string& p) { write_file_atomic(p, js + "\n"); });
  }
  std::string where;
  if (scene.out_of_core()) {
    char buf[96];
    std::snprintf(buf, sizeof buf, ", out of core, %d frames in %.1f s", run.frames, run.seconds);
    where = " (" + scene.name + buf + ")";
  }
  std::printf("%s%s -> %s, %s\n", stats_summary(frame.stats).c_str(), where.c_str(), png.c_str(), exr.c_str());
  if (const std::string remote = remote_summary(); !remote.empty()) std::printf("%s\n", remote.c_str());
#if SL_HAVE_MPI
  if (dist) std::printf("%s\n", dist->summary().c_str());
#endif
  std::fflush(stdout);
  return report_completeness(o, run, png + " and " + exr);
}

int run_render(const RenderCommandOptions& o) {
#if SL_HAVE_MPI
  if (o.render.distributed) return run_distributed([&](Distributed& d) { return render_frames(o, &d); });
#endif
  return render_frames(o, nullptr);
}

}  // namespace

Runner add_render_command(CLI::App& app) {
  auto o = std::make_shared<RenderCommandOptions>();
  CLI::App* c =
      app.add_subcommand("render", "Render a view to PREFIX.png and PREFIX.exr (out of core: until it is complete)");
  o->render.size = "1024x1024";
  add_render_options(*c, o->render, Command::Render);
  c->add_option("--out", o->out, "Output prefix")->capture_default_str();
  CLI::Option* frames = c->add_option(
      "--frames", o->frames,
      "Render exactly this many frames of the view (default: out of core, until the image is complete)");
  CLI::Option* max_frames =
      c->add_option("--max-frames", o->max_frames,
                    "Out of core without --frames: stop after this many frames even if the image is incomplete")
          ->capture_default_str();
  CLI::Option* budget = c->add_option("--time-budget", o->time_budget_s,
                                      "Out of core without --frames: stop after the frame that passes this many "
                                      "seconds even if the image is incomplete (default: none)");
  c->add_flag("--allow-partial", o->allow_partial,
              "Exit 0 when the image is incomplete (out of core; it is written either way, exit 4 without this)");
  c->add_flag("--strict", o->strict, "Exit 1 if any brick failed to load (out of core), even with --allow-partial");
  c->add_option("--stats-json", o->stats_json, "Write frame statistics as JSON");
  return [o, frames, max_frames, budget] {
    o->frames_given = frames->count() > 0;
    o->max_frames_given = max_frames->count() > 0;
    o->time_budget_given = budget->count() > 0;
    return run_render(*o);
  };
}

}  // namespace sl::app
