// `sparseleap render`: one frame to PREFIX.png and PREFIX.exr, a one-line summary, optional stats JSON.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>

#include <tbb/global_control.h>

#include "apps/backend.h"
#include "apps/commands.h"
#include "apps/scene_loader.h"
#include "core/cpu_renderer.h"
#include "core/error.h"

namespace sl::app {

namespace {

struct RenderOptions {
  SceneOptions scene;
  std::string size = "1024x1024";
  std::string mode = "dvr";
  std::string method = "sparseleap";
  std::string backend = "auto";
  std::string out = "sparseleap";
  std::string stats_json;
  std::string view = "image";
  float iso = NAN;
  float step = 0.5f;
  int block = 16;
  int threads = 0;
  bool ert = false;
  bool boxes = false;
};

void write_text_file(const std::string& path, const std::string& text) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp, std::ios::binary);
    if (!(f << text << '\n')) throw InputError(path, "cannot write file");
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) throw InputError(path, "cannot write file: " + ec.message());
}

int run_render(const RenderOptions& o) {
  RenderSettings rs;
  parse_size(o.size, rs.width, rs.height);
  rs.mode = parse_render_mode(o.mode);
  rs.method = parse_skip_method(o.method);
  rs.step = o.step;
  rs.ert = o.ert;
  rs.block = o.block;
  rs.boxes_overlay = o.boxes;
  if (o.view == "depth-complexity") {
    rs.depth_complexity_view = true;
  } else if (o.view != "image") {
    throw InputError("--view", "unknown view '" + o.view + "' (expected image or depth-complexity)");
  }
  check_output_prefix(o.out);
  if (!o.stats_json.empty()) check_output_prefix(o.stats_json);

  std::unique_ptr<tbb::global_control> threads;
  if (o.threads > 0) {
    threads = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, o.threads);
  }

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
  const Backend backend = choose_backend(o.backend);  // after all checks: bad input is the only line
  Frame frame = render_frame(backend, scene, rs);
  write_png(o.out + ".png", frame.image);
  write_exr(o.out + ".exr", frame.image);
  if (!o.stats_json.empty()) write_text_file(o.stats_json, stats_to_json(frame.stats));
  std::printf("%s -> %s.png, %s.exr\n", stats_summary(frame.stats).c_str(), o.out.c_str(), o.out.c_str());
  return 0;
}

}  // namespace

Runner add_render_command(CLI::App& app) {
  auto o = std::make_shared<RenderOptions>();
  CLI::App* c = app.add_subcommand("render", "Render one frame to PREFIX.png and PREFIX.exr");
  c->add_option("--volume", o->scene.volume, "Intensity volume: NRRD (.nrrd/.nhdr) or builtin:KIND[:XxYxZ[:SEED]]; default builtin:neurites (256^3)");
  c->add_option("--labels", o->scene.labels, "Label volume (NRRD, integer type, same dims)");
  c->add_option("--tf", o->scene.tf, "Transfer function JSON");
  c->add_option("--camera", o->scene.camera, "Camera JSON");
  c->add_option("--enable", o->scene.enable, "Enabled labels: all, none, 1,5,10-20 or fraction:P:SEED");
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
  c->add_option("--threads", o->threads, "CPU threads (0 = all)")->capture_default_str();
  c->add_option("--out", o->out, "Output prefix")->capture_default_str();
  c->add_option("--stats-json", o->stats_json, "Write frame statistics as JSON");
  return [o] { return run_render(*o); };
}

}  // namespace sl::app
