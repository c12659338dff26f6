#include "apps/render_options.h"

#include "core/occupancy/fine_occupancy.h"

#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <limits>
#include <regex>

#include "cache/testing/fault_injection.h"
#include "cache/synthetic/procedural_neurites.h"
#include "core/util/error.h"
#include "core/util/process_memory.h"

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

// 0 stands for "not given" in the options' structs (the default applies): a 0 on the command line
// would silently become that default (or, for --cache-mb, in core), so it is refused.
std::function<void(const std::string&)> refuse_zero(const char* option) {
  return [option](const std::string& v) {
    char* end = nullptr;
    const double d = std::strtod(v.c_str(), &end);
    if (end != v.c_str() && *end == '\0' && d == 0.0) throw InputError(option, "must be positive, got " + v);
  };
}

// An empty name stands for "not given" too (the default volume, ramp, camera; no cache).
std::function<void(const std::string&)> refuse_empty(const char* option) {
  return [option](const std::string& v) {
    if (v.empty()) throw InputError(option, "the name is empty");
  };
}

}  // namespace

bool RenderOptions::out_of_core() const { return cache_mb > 0 || distributed || is_procedural_spec(scene.volume); }

void add_render_options(CLI::App& c, RenderOptions& o, Command cmd) {
  const bool view = cmd == Command::View;
  // The viewer's keys for what its options only set at the start.
  const auto key = [&](const char* k) { return view ? std::string(" (key ") + k + ")" : std::string(); };
  SceneOptions& s = o.scene;
  c.add_option("--volume", s.volume,
               "Volume: NRRD (.nrrd/.nhdr), NIfTI-1/-2 (.nii, .nii.gz, .hdr/.img), TIFF stack (.tif/.tiff or a "
               "directory of slices), OME-Zarr v2/v3 store or Neuroglancer precomputed volume (a directory or "
               "http(s):// URL, optionally behind zarr://, zarr2://, zarr3:// or precomputed://; out of core with "
               "--cache-mb), builtin:KIND[:XxYxZ[:SEED]] or procedural:neurites:XxYxZ[:SEED]; default "
               "builtin:neurites (256^3)")
      ->each(refuse_empty("--volume"));
  c.add_option("--labels", s.labels,
               "Label volume of an integer type and the same dims, in any format --volume reads; default: a "
               "store's own labels/ group (a .zarr volume), the built-in set's labels")
      ->each(refuse_empty("--labels"));
  c.add_option("--tf", s.tf, "Transfer function JSON; default: a ramp over 0..255 for u8, over the data range otherwise")
      ->each(refuse_empty("--tf"));
  c.add_option("--disk-cache", s.disk_cache,
               "Directory caching the objects of remote (http/https) stores between runs (LRU, crash-safe)")
      ->each(refuse_empty("--disk-cache"));
  c.add_option("--disk-cache-mb", s.disk_cache_mb, "Bound of --disk-cache in MB (default 1024)")
      ->each(refuse_zero("--disk-cache-mb"));
  if (cmd != Command::Bench) {
    c.add_option("--camera", s.camera, "Camera JSON; default: the whole volume seen from front-right-top")
        ->each(refuse_empty("--camera"));
  }
  c.add_option("--enable", s.enable,
               "Enabled labels: all, none, 1,5,10-20 or fraction:P:SEED; in dvr, mip and iso only samples of "
               "enabled labels contribute; labels mode shows all in core and needs --enable out of core");

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
  c.add_option("--iso-method", o.iso_method,
               "Iso surface: exact (first root of the trilinear interpolant per cell, LR81) or sampled (first "
               "sample pair bracketing the iso value, bisection)" + std::string(view ? " (key E)" : ""))
      ->capture_default_str();
  c.add_option("--filter", o.filter,
               "Reconstruction: linear (trilinear), quadratic or cubic (uniform B-spline, approximating; exact iso "
               "finds the filter's own roots). Out of core the B-splines need --method none" +
                   std::string(view ? " (key F)" : ""))
      ->capture_default_str();
  c.add_option("--step", o.step, "Sample distance in units of the smallest spacing, in [0.001, 64]")->capture_default_str();
  c.add_option("--block", o.block,
               "Culling block edge in voxels: auto (8 in core, 16 out of core), 4, 8, 16 or 32")
      ->capture_default_str();
  c.add_option("--fine-cell", o.fine_cell,
               "Fine occupancy cell edge in voxels inside SparseLeap segments (in core): auto, 4 or 8, 0 = off; "
               "auto is 8 where the voxel mask applies, else 4. The image is the same, only clear cells' samples "
               "are skipped")
      ->capture_default_str();
  c.add_option("--voxel-mask", o.voxel_mask,
               "on|off: inside occupied fine cells, skip the samples whose 2x2x2 voxels cannot contribute (in core, "
               "u8/u16 volumes, dvr and labels, trilinear); the image is the same, fewer samples are fetched")
      ->capture_default_str();
  c.add_option("--tight-boxes", o.tight_boxes,
               "on|off: with the voxel mask, SparseLeap lists come from leaf boxes (sparse subtrees flattened to "
               "their leaves) shrunk to the cells whose samples can contribute (in core; out of core from the resident "
               "bricks' masks, dvr and labels); the image and sample count are the same, the segments shorter")
      ->capture_default_str();
  c.add_option("--simd", o.simd,
               "on|off: the CPU backend takes DVR samples eight at a time with AVX2 where the CPU has it (u8/u16, "
               "unlit, trilinear); the image is the same, off samples one by one")
      ->capture_default_str();
  c.add_flag("--ert", o.ert, "Early ray termination at opacity 0.99");
  c.add_flag("--shade", o.lighting.enabled,
             "dvr and labels: Blinn-Phong lighting with a headlight on the gradient (VTK's model and defaults; "
             "labels: the gradient of each label's mask)" + std::string(view ? " (key L)" : ""));
  c.add_option("--ambient", o.lighting.ambient, "--shade: ambient coefficient in [0, 1]")->capture_default_str();
  c.add_option("--diffuse", o.lighting.diffuse, "--shade: diffuse coefficient in [0, 1]")->capture_default_str();
  c.add_option("--specular", o.lighting.specular, "--shade: specular coefficient in [0, 1]")->capture_default_str();
  c.add_option("--shininess", o.lighting.shininess, "--shade: specular power in [0, 128]")->capture_default_str();
  if (cmd != Command::Bench) {
    c.add_option("--view", o.view, "image or depth-complexity" + key("D"))->capture_default_str();
    c.add_flag("--boxes", o.boxes,
               std::string(view ? "Start with the occupancy-box overlay on" : "Overlay the occupancy geometry") +
                   " (EMPTY red, NON_EMPTY green, UNKNOWN grey)" + key("B"));
  }
  c.add_option("--backend", o.backend, "auto (CUDA when a device is found, else the CPU, saying why), cpu or cuda")
      ->capture_default_str();
  c.add_option("--lists", o.lists, "Segment-list builder: cpu, or gl (OpenGL rasterizer, headless EGL)")
      ->capture_default_str();
  c.add_option("--cuda-sampler", o.cuda_sampler,
               "CUDA backend out of core: slots (software trilinear, the CPU's image) or atlas (3D texture, "
               "hardware trilinear; close to, not bit-identical with, the CPU)")
      ->capture_default_str();
  c.add_option("--threads", o.threads, "CPU threads (0 = all)")->capture_default_str();

  c.add_option("--cache-mb", o.cache_mb,
               std::string("Out of core with this brick-cache budget") +
                   (view ? ": bricks stream in and the view refines" : "") +
                   " (default for procedural: 1024; at most 90 % of the memory available)")
      ->each(refuse_zero("--cache-mb"));
  c.add_option("--brick", o.brick, "Brick payload edge: 8, 16, 32 or 64 (out of core)")->capture_default_str();
  c.add_option("--lod", o.lod, "Pin every sample to this level (out of core; default: from the pixel footprint). When the view's bricks at that level do not fit --cache-mb, the frames go on in depth passes to the exact image");
  c.add_option("--lod-bias", o.lod_bias, "Level-of-detail bias, > 0; > 1 coarser (out of core)")->capture_default_str();
  c.add_option("--pyramid", s.pyramid,
               "Coarse levels shown out of core: mean (each voxel the average of the voxels below) or max (the "
               "largest: thin, sparse structure stays visible when zoomed out). Default: max for procedural "
               "volumes and stores holding max levels (`sparseleap ingest` writes them), mean otherwise")
      ->check(CLI::IsMember({"mean", "max"}));
  c.add_option("--retire-frames", o.retire_frames,
               "Retire occupancy-tree nodes unused this many frames (out of core)")
      ->capture_default_str();
  if (cmd == Command::Render) o.upload_budget = 0;
  c.add_option("--upload-budget", o.upload_budget,
               "Bricks made resident per frame at most, out of core (0: every brick the loader has finished; "
               "render's default, since its frames only converge; view and bench take 512 so that a frame's "
               "time stays bounded)")
      ->capture_default_str();
  c.add_option("--prefetch", o.prefetch,
               std::string("on or off: out of core, once a frame is complete, load the next-finer level around "
                           "the view's focus") +
                   (cmd != Command::Render ? " and along the camera's motion (next view extrapolated)" : "") +
                   " within the upload budget and spare cache room; never evicts bricks the view uses")
      ->capture_default_str();
  c.add_option("--inject-faults", s.inject_faults,
               "Testing aid, out of core: make brick reads fail, e.g. permanent=0.02,transient=0.06,short=0.02,"
               "recover=2,delay=0.1,delay-ms=5,seed=7 (shares of bricks; transient and short reads fail their "
               "first 1..recover attempts and are retried with backoff)")
      ->check(CLI::Validator(
          [](const std::string& v) {
            try {
              parse_fault_spec(v);
              return std::string();
            } catch (const InputError& e) {
              return e.reason();
            }
          },
          "SPEC"));
  if (cmd != Command::View) {
    c.add_flag("--distributed", o.distributed,
               "Sort-last under mpirun: each rank renders its k-d region of the volume out of core, IceT "
               "composites, rank 0 writes (dvr, iso, labels; --ert is per rank, not exact)");
  }
}

void check_cache_budget(std::size_t cache_mb) {
  if (cache_mb == 0) return;
  const double available = available_memory_mb();
  // The frame's buffers, the page tables and the loader's bricks come on top of the cache.
  const double limit = available * kCacheShareOfAvailableMemory;
  if (available > 0 && double(cache_mb) > limit) {
    char buf[200];
    std::snprintf(buf, sizeof buf,
                  "%zu MB is more than this machine can hold: %.0f MB of memory available, of which the cache may "
                  "take %.0f MB",
                  cache_mb, available, std::floor(limit));
    throw InputError("--cache-mb", buf);
  }
}

int parse_block(const std::string& text, bool out_of_core) {
  if (text == "auto") return out_of_core ? kOutOfCoreBlock : kInCoreBlock;
  if (text != "4" && text != "8" && text != "16" && text != "32") {
    throw InputError("--block", "culling block size must be auto, 4, 8, 16 or 32 (got '" + text + "')");
  }
  return std::stoi(text);
}

CheckedOptions check_render_options(const RenderOptions& o) {
  CheckedOptions c;
  RenderSettings& rs = c.settings;
  parse_size(o.size, rs.width, rs.height);
  rs.mode = parse_render_mode(o.mode);
  rs.method = parse_skip_method(o.method);
  rs.iso_method = parse_iso_method(o.iso_method);
  rs.filter = parse_filter(o.filter);
  rs.step = o.step;
  rs.ert = o.ert;
  rs.lighting = o.lighting;
  validate_lighting(o.lighting);
  rs.block = parse_block(o.block, o.out_of_core());
  if (o.fine_cell == "auto") {
    rs.fine_cell = kFineCellAuto;
  } else if (o.fine_cell == "0" || o.fine_cell == "4" || o.fine_cell == "8") {
    rs.fine_cell = std::stoi(o.fine_cell);
  } else {
    throw InputError("--fine-cell", "must be auto, 0 (off), 4 or 8 voxels, not '" + o.fine_cell + "'");
  }
  if (o.voxel_mask != "on" && o.voxel_mask != "off") {
    throw InputError("--voxel-mask", "must be on or off, not '" + o.voxel_mask + "'");
  }
  rs.voxel_mask = o.voxel_mask == "on";
  if (o.tight_boxes != "on" && o.tight_boxes != "off") {
    throw InputError("--tight-boxes", "must be on or off, not '" + o.tight_boxes + "'");
  }
  rs.tight_boxes = o.tight_boxes == "on";
  if (o.simd != "on" && o.simd != "off") throw InputError("--simd", "must be on or off, not '" + o.simd + "'");
  rs.simd = o.simd == "on";
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
  check_cache_budget(o.cache_mb);
  // The same wrap would read as a huge budget, i.e. no bound at all.
  if (o.upload_budget > std::size_t(PTRDIFF_MAX)) {
    throw InputError("--upload-budget", "must be 0 (every loaded brick) or a number of bricks");
  }
  if (o.threads < 0) throw InputError("--threads", "must be 0 (all cores) or a number of threads");
  if (o.scene.disk_cache_mb > std::size_t(PTRDIFF_MAX) >> 20) throw InputError("--disk-cache-mb", "must be positive");
  if (o.scene.disk_cache_mb > 0 && o.scene.disk_cache.empty()) {
    throw InputError("--disk-cache-mb", "needs --disk-cache DIR");
  }
  if (!(o.lod_bias > 0.0f) || !std::isfinite(o.lod_bias)) throw InputError("--lod-bias", "must be positive");
  if (o.lod < -1) throw InputError("--lod", "must be a level (0: full resolution)");
  if (o.prefetch != "on" && o.prefetch != "off") throw InputError("--prefetch", "must be on or off");
  if (o.out_of_core() && !out_of_core_method(rs.method)) {
    throw InputError("--method", "out-of-core rendering supports sparseleap and none");
  }
  if (!o.scene.inject_faults.empty() && !o.out_of_core()) {
    throw InputError("--inject-faults", "faults are injected into out-of-core brick reads: add --cache-mb");
  }
  if (o.distributed) {
#ifndef SL_HAVE_MPI
    throw InputError("--distributed", "this build has no MPI and IceT (configure with -DSL_MPI=ON; Debian's "
                                      "libopenmpi-dev and paraview-dev)");
#endif
    // MIP takes the maximum along the ray, which the ordered "over" of RGBA cannot composite.
    if (rs.mode == RenderMode::Mip) throw InputError("--distributed", "mip mode is not supported (dvr, iso, labels)");
    if (rs.depth_complexity_view || rs.boxes_overlay) {
      throw InputError("--distributed", "the depth-complexity view and --boxes are single-process overlays");
    }
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
  os.upload_budget = o.upload_budget == 0 ? std::numeric_limits<std::size_t>::max() : o.upload_budget;
  os.prefetch = o.prefetch == "on";
  return os;
}

}  // namespace sl::app
