// `sparseleap render`: one frame to PREFIX.png and PREFIX.exr, a one-line summary, optional stats JSON.
#include <unistd.h>

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

struct RenderCommandOptions {
  RenderOptions render;
  std::string out = "sparseleap";
  std::string stats_json;
  int frames = 1;
  bool strict = false;
};

// One line when the last frame stops short of complete or was coarsened for cache pressure, and why.
std::string pressure_message(const CacheStats& c, int frames) {
  if (!c.present || (c.completeness >= 1.0 && c.lod_coarsened <= 0.0)) return {};
  char buf[256];
  std::string why;
  if (c.working_set_mb > 0) {
    std::snprintf(buf, sizeof buf, "the view needs about %.1f MB at level %d; the cache has %.1f MB", c.working_set_mb,
                  c.working_set_level, c.cache_mb);
    why = buf;
  } else if (c.failed > 0 && c.bricks_missing == 0 && c.pending == 0) {
    std::snprintf(buf, sizeof buf, "%llu bricks failed to load", (unsigned long long)c.failed);
    why = buf;
  } else {
    std::snprintf(buf, sizeof buf, "bricks were still loading after %d frames (more --frames)", frames);
    why = buf;
  }
  if (c.completeness < 1.0) {
    std::snprintf(buf, sizeof buf, "incomplete (completeness %.3f, %llu bricks missing): ", c.completeness,
                  (unsigned long long)c.bricks_missing);
  } else {
    std::snprintf(buf, sizeof buf, "%.1f%% of samples coarser than the pixel footprint asks: ", 100.0 * c.lod_coarsened);
  }
  return buf + why;
}

// Out of core the volume is read through the page table and brick cache, bricks stream in over the
// frames (a progress line on a terminal); the last frame is written. Distributed (`dist`), every rank
// renders its region's frames and the last is composited; rank 0 writes it.
int render_frames(const RenderCommandOptions& o, [[maybe_unused]] Distributed* dist) {
  const RenderOptions& ro = o.render;
  const CheckedOptions checked = check_render_options(ro);
  const std::string png = output_with_extension(o.out, ".png"), exr = output_with_extension(o.out, ".exr");
  OutputFiles outputs;
  outputs.add(png);
  outputs.add(exr);
  if (!o.stats_json.empty()) outputs.add(o.stats_json);
  if (o.frames < 1 || o.frames > 100000) throw InputError("--frames", "must be between 1 and 100000");
  const ThreadLimit threads(ro.threads);

  const SourceScene scene = load_source_scene(ro.scene, ro.out_of_core());
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
  const LabelSet* enabled = scene.enabled ? &*scene.enabled : nullptr;
#if SL_HAVE_MPI
  if (dist) {
    const CullParams cull{rs.mode, &scene.tf, rs.iso, enabled};
    OutOfCoreRenderer& r = *renderer.out_of_core();
    r.set_sample_clip(dist->balance(*scene.source, r.layout(), rs.block, cull).clip);
  }
#endif
  Frame frame;
  for (int f = 0; f < o.frames; ++f) {
    frame = renderer.render(scene.tf, enabled, scene.camera, rs);
    if (progress) {
      std::fprintf(stderr, "\r  frame %u/%d: %.0f ms, %llu loads, %llu misses, %llu pending   ", frame.stats.cache.frame,
                   o.frames, frame.stats.time_ms.total, (unsigned long long)frame.stats.cache.loads,
                   (unsigned long long)frame.stats.cache.misses, (unsigned long long)frame.stats.cache.pending);
    }
  }
  if (progress) std::fprintf(stderr, "\r%70s\r", "");
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
  const std::string where = scene.out_of_core() ? " (" + scene.name + ", out of core)" : "";
  std::printf("%s%s -> %s, %s\n", stats_summary(frame.stats).c_str(), where.c_str(), png.c_str(), exr.c_str());
  if (const std::string remote = remote_summary(); !remote.empty()) std::printf("%s\n", remote.c_str());
#if SL_HAVE_MPI
  if (dist) std::printf("%s\n", dist->summary().c_str());
#endif
  std::size_t failed = renderer.out_of_core() ? renderer.out_of_core()->failed_bricks() : 0;
#if SL_HAVE_MPI
  if (dist) failed = std::size_t(frame.stats.cache.failed);  // every rank's, summed by the composite
#endif
  if (o.strict && failed > 0) {
    std::fprintf(stderr, "sparseleap: error: %zu bricks failed to load (--strict)\n", failed);
    return 1;
  }
  const std::string shortfall = pressure_message(frame.stats.cache, o.frames);
  if (!shortfall.empty()) std::fprintf(stderr, "sparseleap: %s\n", shortfall.c_str());
  if (o.strict && frame.stats.cache.present && frame.stats.cache.completeness < 1.0) {
    std::fprintf(stderr, "sparseleap: error: the last frame is incomplete (--strict)\n");
    return 1;
  }
  return 0;
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
  CLI::App* c = app.add_subcommand("render", "Render one frame to PREFIX.png and PREFIX.exr");
  o->render.size = "1024x1024";
  add_render_options(*c, o->render, Command::Render);
  c->add_option("--out", o->out, "Output prefix")->capture_default_str();
  c->add_option("--frames", o->frames, "Frames of the same view (out of core: the cache fills and converges)")
      ->capture_default_str();
  c->add_flag("--strict", o->strict, "Exit non-zero at the end if any brick failed to load (out of core)");
  c->add_option("--stats-json", o->stats_json, "Write frame statistics as JSON");
  return [o] { return run_render(*o); };
}

}  // namespace sl::app
