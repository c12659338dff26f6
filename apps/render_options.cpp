#include "apps/render_options.h"

#include "core/fine_occupancy.h"

#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <regex>

#include "cache/synthetic/procedural_neurites.h"
#include "core/error.h"

namespace sl::app {

namespace {

// "WxH"; InputError("--size", ...) otherwise.
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

}  // namespace

bool RenderOptions::out_of_core() const { return cache_mb > 0 || is_procedural_spec(scene.volume); }

void add_render_options(CLI::App& c, RenderOptions& o, Command cmd) {
  const bool view = cmd == Command::View;
  // The viewer's keys for what its options only set at the start.
  const auto key = [&](const char* k) { return view ? std::string(" (key ") + k + ")" : std::string(); };
  SceneOptions& s = o.scene;
  c.add_option("--volume", s.volume,
               "Volume: NRRD (.nrrd/.nhdr), NIfTI-1 (.nii/.nii.gz), TIFF stack (.tif/.tiff or a directory), OME-Zarr store (.zarr; out of core with --cache-mb), "
               "builtin:KIND[:XxYxZ[:SEED]] or procedural:neurites:XxYxZ[:SEED]; default builtin:neurites (256^3)");
  c.add_option("--labels", s.labels,
               "Label volume (NRRD or .zarr store, integer type, same dims); a .zarr volume's own labels/ group is "
               "used when this is not given");
  c.add_option("--tf", s.tf, "Transfer function JSON");
  if (cmd != Command::Bench) c.add_option("--camera", s.camera, "Camera JSON");
  c.add_option("--enable", s.enable, "Enabled labels: all, none, 1,5,10-20 or fraction:P:SEED");

  c.add_option("--size", o.size,
               view ? "Rendered canvas WxH (the window adds a control panel at its left)" : "Image size WxH")
      ->capture_default_str();
  c.add_option("--mode", o.mode, view ? "dvr, mip, iso or labels (key M cycles)" : "dvr, mip, iso or labels")
      ->capture_default_str();
  if (cmd != Command::Bench) {
    c.add_option("--method", o.method,
                 "none, bbox, octree or sparseleap (out of core: sparseleap or none)" + std::string(view ? " (keys 1-4)" : ""))
        ->capture_default_str();
  }
  // NaN is the "not given" default, so a given NaN (or ±Inf) is refused while parsing.
  c.add_option("--iso", o.iso, "Iso value (iso mode); default 128 for u8, mid-range otherwise")
      ->check(CLI::Validator(
          [](const std::string& v) {
            const float f = std::strtof(v.c_str(), nullptr);
            return std::isfinite(f) ? std::string() : std::string("must be a finite number");
          },
          "FINITE"));
  c.add_option("--step", o.step, "Sample distance in units of the smallest spacing, in [0.001, 64]")->capture_default_str();
  c.add_option("--block", o.block, "Culling block edge in voxels: 4, 8, 16 or 32")->capture_default_str();
  c.add_option("--fine-cell", o.fine_cell,
               "Fine occupancy cell edge in voxels inside SparseLeap segments (in core): 4 or 8, 0 = off; the "
               "image is the same, only clear cells' samples are skipped")
      ->capture_default_str();
  c.add_flag("--ert", o.ert, "Early ray termination at opacity 0.99");
  if (cmd != Command::Bench) {
    c.add_option("--view", o.view, "image or depth-complexity" + key("D"))->capture_default_str();
    c.add_flag("--boxes", o.boxes,
               std::string(view ? "Start with the occupancy-box overlay on" : "Overlay the occupancy geometry") +
                   " (EMPTY red, NON_EMPTY green, UNKNOWN grey)" + key("B"));
  }
  c.add_option("--backend", o.backend, "auto, cpu or cuda")->capture_default_str();
  c.add_option("--lists", o.lists, "Segment-list builder: cpu, or gl (OpenGL rasterizer, headless EGL)")
      ->capture_default_str();
  c.add_option("--cuda-sampler", o.cuda_sampler,
               "CUDA backend out of core: slots (software trilinear, the CPU's image) or atlas (3D texture, "
               "hardware trilinear; close to, not bit-identical with, the CPU)")
      ->capture_default_str();
  c.add_option("--threads", o.threads, "CPU threads (0 = all)")->capture_default_str();

  c.add_option("--cache-mb", o.cache_mb,
               std::string("Out of core with this brick-cache budget") +
                   (view ? ": bricks stream in and the view refines" : "") + " (default for procedural: 1024)");
  c.add_option("--brick", o.brick, "Brick payload edge: 8, 16, 32 or 64 (out of core)")->capture_default_str();
  c.add_option("--lod", o.lod, "Pin every sample to this level (out of core; default: from the pixel footprint)");
  c.add_option("--lod-bias", o.lod_bias, "Level-of-detail bias, > 0; > 1 coarser (out of core)")->capture_default_str();
  c.add_option("--retire-frames", o.retire_frames,
               "Retire occupancy-tree nodes unused this many frames (out of core)")
      ->capture_default_str();
}

CheckedOptions check_render_options(const RenderOptions& o) {
  CheckedOptions c;
  RenderSettings& rs = c.settings;
  parse_size(o.size, rs.width, rs.height);
  rs.mode = parse_render_mode(o.mode);
  rs.method = parse_skip_method(o.method);
  rs.step = o.step;
  rs.ert = o.ert;
  rs.block = o.block;
  rs.fine_cell = o.fine_cell;
  validate_fine_cell(o.fine_cell);
  rs.boxes_overlay = o.boxes;
  if (o.view == "depth-complexity") {
    rs.depth_complexity_view = true;
  } else if (o.view != "image") {
    throw InputError("--view", "unknown view '" + o.view + "' (expected image or depth-complexity)");
  }
  // Bounded below so a ray takes at most ~1000 samples per voxel edge: --step 1e-9 would never finish.
  if (!(o.step >= 1e-3f) || o.step > 64.0f) throw InputError("--step", "step must be in [0.001, 64]");
  // A negative --cache-mb wraps to a huge unsigned budget (and then "out of memory").
  if (o.cache_mb > std::size_t(PTRDIFF_MAX)) throw InputError("--cache-mb", "must be positive");
  if (o.threads < 0) throw InputError("--threads", "must be 0 (all cores) or a number of threads");
  if (!(o.lod_bias > 0.0f) || !std::isfinite(o.lod_bias)) throw InputError("--lod-bias", "must be positive");
  if (o.lod < -1) throw InputError("--lod", "must be a level (0: full resolution)");
  if (o.out_of_core() && !out_of_core_method(rs.method)) {
    throw InputError("--method", "out-of-core rendering supports sparseleap and none");
  }
  c.lists = parse_list_source(o.lists);
  c.cuda_sampler = parse_cuda_sampler(o.cuda_sampler);
  if (c.cuda_sampler == CudaSampler::Atlas) {
#ifndef SL_HAVE_CUDA
    throw InputError("--cuda-sampler", "atlas: this build has no CUDA backend (nvcc was not found)");
#endif
    if (o.backend == "cpu") throw InputError("--cuda-sampler", "atlas needs the CUDA backend (--backend cuda or auto)");
    if (!o.out_of_core()) {
      throw InputError("--cuda-sampler", "atlas samples the out-of-core brick cache: use it with --cache-mb");
    }
  }
  return c;
}

void complete_settings(const RenderOptions& o, const SourceScene& s, RenderSettings& rs) {
  if (rs.mode == RenderMode::Labels) {
    if (!s.labelled) throw InputError("--mode", "labels mode needs a label volume (--labels)");
    if (s.out_of_core() && !s.enabled) {
      throw InputError("--mode", "labels mode out of core needs --enable (the set of labels to show)");
    }
  }
  rs.iso = !std::isnan(o.iso) ? o.iso : s.desc.type == VoxelType::U8 ? 128.0f : 0.5f * (s.tf.vmin() + s.tf.vmax());
  // A degenerate camera fails here, before any frame, naming its file.
  make_ray_generator(s.camera, rs.width, rs.height, o.scene.camera.empty() ? "camera" : o.scene.camera);
}

OutOfCoreSettings out_of_core_settings(const RenderOptions& o) {
  OutOfCoreSettings os;
  os.brick = o.brick;
  os.cache_mb = o.cache_mb > 0 ? o.cache_mb : 1024;
  os.lod = o.lod;
  os.lod_bias = o.lod_bias;
  os.retire_frames = o.retire_frames;
  return os;
}

}  // namespace sl::app
