#include "apps/scene_loader.h"

#include <CLI/CLI.hpp>
#include <cstdio>
#include <regex>

#include "cache/generate.h"
#include "cache/nrrd.h"
#include "core/error.h"

namespace sl::app {

void parse_size(const std::string& s, int& w, int& h) {
  static const std::regex re("^([0-9]{1,6})[xX]([0-9]{1,6})$");
  std::smatch m;
  if (!std::regex_match(s, m, re)) throw InputError("--size", "expected WxH, e.g. 1024x768, got '" + s + "'");
  w = std::stoi(m[1]);
  h = std::stoi(m[2]);
  if (w < 1 || h < 1 || w > 16384 || h > 16384) {
    throw InputError("--size", "width and height must be between 1 and 16384");
  }
}

namespace {

// "builtin:KIND[:XxYxZ[:SEED]]": a generated data set held in memory (no file).
GeneratedVolume load_builtin(const std::string& spec) {
  static const std::regex re("^builtin:([a-z]+)(?::([0-9]{1,5})x([0-9]{1,5})x([0-9]{1,5}))?(?::([0-9]{1,9}))?$");
  std::smatch m;
  if (!std::regex_match(spec, m, re)) {
    throw InputError(spec, "expected builtin:KIND[:XxYxZ[:SEED]], e.g. builtin:neurites:512x512x512");
  }
  const ivec3 dims = m[2].matched ? ivec3(std::stoi(m[2]), std::stoi(m[3]), std::stoi(m[4])) : ivec3(kBuiltinSize);
  const std::uint32_t seed = m[5].matched ? std::uint32_t(std::stoul(m[5])) : 1u;
  return generate_volume(m[1], dims, seed);
}

}  // namespace

void add_scene_options(CLI::App& c, SceneOptions& s, bool camera) {
  c.add_option("--volume", s.volume,
               "Volume: NRRD (.nrrd/.nhdr), builtin:KIND[:XxYxZ[:SEED]] or procedural:neurites:XxYxZ[:SEED]; "
               "default builtin:neurites (256^3)");
  c.add_option("--labels", s.labels, "Label volume (NRRD, integer type, same dims)");
  c.add_option("--tf", s.tf, "Transfer function JSON");
  if (camera) c.add_option("--camera", s.camera, "Camera JSON");
  c.add_option("--enable", s.enable, "Enabled labels: all, none, 1,5,10-20 or fraction:P:SEED");
}

RenderSettings make_render_settings(const std::string& size, const std::string& mode, const std::string& method,
                                    const std::string& view, float step, bool ert, int block, bool boxes) {
  RenderSettings rs;
  parse_size(size, rs.width, rs.height);
  rs.mode = parse_render_mode(mode);
  rs.method = parse_skip_method(method);
  rs.step = step;
  rs.ert = ert;
  rs.block = block;
  rs.boxes_overlay = boxes;
  if (view == "depth-complexity") {
    rs.depth_complexity_view = true;
  } else if (view != "image") {
    throw InputError("--view", "unknown view '" + view + "' (expected image or depth-complexity)");
  }
  return rs;
}

SourceScene load_source_scene(const SceneOptions& o, bool out_of_core) {
  SourceScene s;
  if (is_procedural_spec(o.volume)) {
    if (!o.labels.empty()) throw InputError("--labels", "a procedural volume has its own labels");
    if (!o.enable.empty()) {
      throw InputError("--enable", "label subsets of procedural volumes are not supported (their ids are hashed)");
    }
    s.source = parse_volume_spec(o.volume);
    s.name = o.volume;
    s.desc = s.source->desc();
    s.tf = o.tf.empty() ? default_transfer_function(0.0f, 255.0f) : load_transfer_function(o.tf);
    s.camera = o.camera.empty() ? default_camera(s.desc.extent()) : load_camera(o.camera);
    return s;
  }
  LoadedScene ls = load_scene(o);
  s.name = ls.name;
  s.desc = ls.volume.desc();
  s.label_count = ls.label_count;
  s.tf = std::move(ls.tf);
  s.camera = ls.camera;
  s.enabled = std::move(ls.enabled);
  s.volume = std::make_shared<const Volume>(std::move(ls.volume));
  if (!ls.labels.empty()) s.labels = std::make_shared<const Volume>(std::move(ls.labels));
  if (out_of_core) s.source = std::make_shared<MemoryVolumeSource>(s.volume, s.labels, s.name);
  return s;
}

LoadedScene load_scene(const SceneOptions& o) {
  LoadedScene s;
  if (o.volume.empty() || o.volume.rfind("builtin:", 0) == 0) {
    const std::string spec = o.volume.empty() ? "builtin:neurites" : o.volume;
    GeneratedVolume g = load_builtin(spec);
    s.volume = std::move(g.intensity);
    s.labels = std::move(g.labels);
    s.label_count = g.label_count;
    s.name = spec;
  } else {
    s.volume = read_nrrd(o.volume);
    s.name = o.volume;
  }
  if (!o.labels.empty()) {
    s.labels = read_nrrd(o.labels);
    if (s.labels.dims() != s.volume.dims()) {
      throw InputError(o.labels, "label volume dims differ from the intensity volume's");
    }
    if (s.labels.type() == VoxelType::F32) throw InputError(o.labels, "label volume must be of an integer type");
    s.label_count = 0;
  }
  if (!s.labels.empty() && s.label_count == 0) s.label_count = max_label(s.labels);

  if (!o.tf.empty()) {
    s.tf = load_transfer_function(o.tf);
  } else if (s.volume.type() == VoxelType::U8) {
    s.tf = default_transfer_function(0.0f, 255.0f);
  } else {
    const vec2 r = value_range(s.volume);
    s.tf = default_transfer_function(r.x, r.y > r.x ? r.y : r.x + 1.0f);
  }
  s.camera = o.camera.empty() ? default_camera(s.volume.desc().extent()) : load_camera(o.camera);
  if (!o.enable.empty()) {
    if (s.labels.empty()) throw InputError("--enable", "needs a label volume (--labels)");
    s.enabled = parse_enable_spec(o.enable, s.label_count);
  }
  return s;
}

}  // namespace sl::app
