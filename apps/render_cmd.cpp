// `sparseleap render`: one frame to PREFIX.png and PREFIX.exr, a one-line summary, optional stats JSON.
#include <cstdio>
#include <memory>

#include <tbb/global_control.h>

#include <unistd.h>

#include <optional>

#include "apps/backend.h"
#include "cache/out_of_core.h"
#include "cache/synthetic/procedural_neurites.h"
#include "cache/volume_source.h"
#include "apps/commands.h"
#include "apps/scene_loader.h"
#include "core/atomic_file.h"
#include "core/frame.h"
#include "core/error.h"

namespace sl::app {

namespace {

struct RenderOptions {
  SceneOptions scene;
  std::string size = "1024x1024";
  std::string mode = "dvr";
  std::string method = "sparseleap";
  std::string backend = "auto";
  std::string lists = "cpu";
  std::string out = "sparseleap";
  std::string stats_json;
  std::string view = "image";
  float iso = NAN;
  float step = 0.5f;
  int block = 16;
  int threads = 0;
  bool ert = false;
  bool boxes = false;
  // Out-of-core path.
  int frames = 1;
  std::size_t cache_mb = 0;  // 0: in core (unless the volume is procedural)
  int brick = 32;
  int lod = -1;
  float lod_bias = 1.0f;
  unsigned retire_frames = 60;
  bool strict = false;
};

// Out of core: the volume is read through the page table and brick cache, bricks stream in over
// frames; the last frame is written.
int run_out_of_core(const RenderOptions& o, RenderSettings rs) {
  const ListSource lists = parse_list_source(o.lists);
  SourceScene ss = load_source_scene(o.scene, true);
  const std::shared_ptr<const VolumeSource>& source = ss.source;
  const TransferFunction& tf = ss.tf;
  const Camera& camera = ss.camera;
  const std::optional<LabelSet>& enabled = ss.enabled;
  const std::string& name = ss.name;
  if (rs.mode == RenderMode::Labels && !enabled) {
    throw InputError("--mode", "labels mode out of core needs --enable (the set of labels to show)");
  }
  rs.iso = std::isnan(o.iso) ? (source->desc().type == VoxelType::U8 ? 128.0f : 0.5f * (tf.vmin() + tf.vmax())) : o.iso;
  if (rs.method != SkipMethod::SparseLeap && rs.method != SkipMethod::None) {
    throw InputError("--method", "out-of-core rendering supports sparseleap and none");
  }
  OutOfCoreSettings os;
  os.brick = o.brick;
  os.cache_mb = o.cache_mb > 0 ? o.cache_mb : 1024;
  os.lod = o.lod;
  os.lod_bias = o.lod_bias;
  os.retire_frames = o.retire_frames;
  if (!(o.lod_bias > 0.0f)) throw InputError("--lod-bias", "must be positive");
  std::string notice;  // printed once the renderer accepted the sizes: bad input stays one line
  const Backend backend = choose_backend(o.backend, &notice);
  OutOfCoreRenderer renderer(source, os, rs.block, make_cast_device(backend));
  if (lists == ListSource::Gl) renderer.set_list_builder(make_gl_list_builder());
  if (!notice.empty()) std::fputs(notice.c_str(), stderr);
  OutOfCoreScene scene{&tf, enabled ? &*enabled : nullptr, camera};
  const bool tty = ::isatty(2);
  Frame frame = render_frames(renderer, scene, rs, o.frames, [&](const Frame& f) {
    if (tty) {
      std::fprintf(stderr, "\r  frame %u/%d: %.0f ms, %llu loads, %llu misses, %llu pending   ", f.stats.cache.frame,
                   o.frames, f.stats.time_ms.total, (unsigned long long)f.stats.cache.loads,
                   (unsigned long long)f.stats.cache.misses, (unsigned long long)f.stats.cache.pending);
    }
  });
  if (tty) std::fprintf(stderr, "\r%70s\r", "");
  write_png(o.out + ".png", frame.image);
  write_exr(o.out + ".exr", frame.image);
  if (!o.stats_json.empty()) write_file_atomic(o.stats_json, stats_to_json(frame.stats) + "\n");
  std::printf("%s (%s, %s) -> %s.png, %s.exr\n", stats_summary(frame.stats).c_str(), name.c_str(),
              "out of core", o.out.c_str(), o.out.c_str());
  if (o.strict && renderer.failed_bricks() > 0) {
    std::fprintf(stderr, "sparseleap: error: %zu bricks failed to load (--strict)\n", renderer.failed_bricks());
    return 1;
  }
  return 0;
}

int run_render(const RenderOptions& o) {
  RenderSettings rs = make_render_settings(o.size, o.mode, o.method, o.view, o.step, o.ert, o.block, o.boxes);
  check_output_prefix(o.out);
  if (!o.stats_json.empty()) check_output_prefix(o.stats_json);

  std::unique_ptr<tbb::global_control> threads;
  if (o.threads > 0) {
    threads = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, o.threads);
  }

  if (o.frames < 1 || o.frames > 100000) throw InputError("--frames", "must be between 1 and 100000");
  if (is_procedural_spec(o.scene.volume) || o.cache_mb > 0) return run_out_of_core(o, rs);
  LoadedScene ls = load_scene(o.scene);
  if (std::isnan(o.iso)) {
    rs.iso = ls.volume.type() == VoxelType::U8 ? 128.0f : 0.5f * (ls.tf.vmin() + ls.tf.vmax());
  } else {
    rs.iso = o.iso;
  }
  Scene scene;
  scene.volume = &ls.volume;
  scene.labels = ls.labels.empty() ? nullptr : &ls.labels;
  scene.tf = &ls.tf;
  scene.enabled = ls.enabled ? &*ls.enabled : nullptr;
  scene.camera = ls.camera;

  validate(scene, rs);
  const ListSource lists = parse_list_source(o.lists);
  const Backend backend = choose_backend(o.backend);  // after all checks: bad input is the only line
  FrameRenderer renderer(backend, lists);
  Frame frame;
  for (int f = 0; f < o.frames; ++f) frame = renderer.render(scene, rs);
  write_png(o.out + ".png", frame.image);
  write_exr(o.out + ".exr", frame.image);
  if (!o.stats_json.empty()) write_file_atomic(o.stats_json, stats_to_json(frame.stats) + "\n");
  std::printf("%s -> %s.png, %s.exr\n", stats_summary(frame.stats).c_str(), o.out.c_str(), o.out.c_str());
  return 0;
}

}  // namespace

Runner add_render_command(CLI::App& app) {
  auto o = std::make_shared<RenderOptions>();
  CLI::App* c = app.add_subcommand("render", "Render one frame to PREFIX.png and PREFIX.exr");
  add_scene_options(*c, o->scene, true);
  c->add_option("--size", o->size, "Image size WxH")->capture_default_str();
  c->add_option("--mode", o->mode, "dvr, mip, iso or labels")->capture_default_str();
  c->add_option("--method", o->method, "none, bbox, octree or sparseleap")->capture_default_str();
  c->add_option("--iso", o->iso, "Iso value (iso mode); default 128 for u8, mid-range otherwise");
  c->add_option("--step", o->step, "Sample distance in units of the smallest spacing")->capture_default_str();
  c->add_option("--block", o->block, "Culling block edge in voxels: 4, 8, 16 or 32")->capture_default_str();
  c->add_flag("--ert", o->ert, "Early ray termination at opacity 0.99");
  c->add_option("--view", o->view, "image or depth-complexity")->capture_default_str();
  c->add_flag("--boxes", o->boxes, "Overlay the occupancy geometry (EMPTY red, NON_EMPTY green, UNKNOWN grey)");
  c->add_option("--backend", o->backend, "auto, cpu or cuda")->capture_default_str();
  c->add_option("--lists", o->lists, "Segment-list builder: cpu, or gl (OpenGL rasterizer, headless EGL)")
      ->capture_default_str();
  c->add_option("--threads", o->threads, "CPU threads (0 = all)")->capture_default_str();
  c->add_option("--out", o->out, "Output prefix")->capture_default_str();
  c->add_option("--frames", o->frames, "Frames of the same view (out of core: the cache fills and converges)")
      ->capture_default_str();
  c->add_option("--cache-mb", o->cache_mb, "Out of core with this brick-cache budget (default for procedural: 1024)");
  c->add_option("--brick", o->brick, "Brick payload edge: 8, 16, 32 or 64 (out of core)")->capture_default_str();
  c->add_option("--lod", o->lod, "Pin every sample to this level (out of core; default: from the pixel footprint)");
  c->add_option("--lod-bias", o->lod_bias, "Level-of-detail bias (>1 coarser)")->capture_default_str();
  c->add_option("--retire-frames", o->retire_frames, "Retire occupancy-tree nodes unused this many frames")
      ->capture_default_str();
  c->add_flag("--strict", o->strict, "Exit non-zero at the end if any brick failed to load");
  c->add_option("--stats-json", o->stats_json, "Write frame statistics as JSON");
  return [o] { return run_render(*o); };
}

}  // namespace sl::app
