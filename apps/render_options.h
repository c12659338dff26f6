// The render options `render`, `bench` and `view` share: registered once, with one help text each,
// and checked once, so every command accepts the same flags and rejects bad values with the same
// line (`sparseleap: error: OPTION: reason`).
#pragma once

#include <cmath>
#include <cstddef>
#include <string>

#include "apps/backend.h"
#include "apps/scene_loader.h"
#include "cache/out_of_core/renderer.h"
#include "core/frame/frame.h"

namespace CLI {
class App;
}

namespace sl::app {

enum class Command { Render, Bench, View };

struct RenderOptions {
  SceneOptions scene;           // --volume --labels --tf --enable, --camera (render, view)
  std::string size;             // WxH; the default is the command's
  std::string mode = "dvr";
  std::string method = "sparseleap";  // render, view (bench takes --methods)
  std::string view = "image";         // render, view
  bool boxes = false;                 // render, view
  float iso = NAN;              // NaN: 128 for u8, else the transfer function's mid-range
  std::string iso_method = "exact";
  std::string filter = "linear";
  float step = 0.5f;
  std::string block = "auto";  // auto: 8 in core, 16 out of core (kInCoreBlock, kOutOfCoreBlock)
  std::string fine_cell = "auto";  // fine occupancy cells inside SparseLeap segments: auto, 0 (off), 4, 8
  std::string voxel_mask = "on";  // on|off: the per-sample bit inside occupied fine cells
  std::string tight_boxes = "on";  // on|off: with the voxel mask, lists from leaf boxes shrunk to its set cells
  std::string simd = "on";        // on|off: the CPU's eight-sample DVR batch (AVX2 where it runs)
  bool ert = false;
  Lighting lighting;            // --shade --ambient --diffuse --specular --shininess (dvr)
  std::string backend = "auto";
  std::string lists = "cpu";
  std::string cuda_sampler = "slots";
  int threads = 0;
  // Out of core.
  std::size_t cache_mb = 0;     // 0: in core, unless the volume is procedural (then 1024)
  int brick = 32;
  int lod = -1;
  float lod_bias = 1.0f;
  unsigned retire_frames = 60;
  // Bricks made resident per frame at most (OutOfCoreSettings::upload_budget); 0: every brick the
  // loader has finished. add_render_options sets the command's default: 0 for render, whose frames
  // only converge, 512 for view and bench, whose frames keep a bounded time.
  std::size_t upload_budget = 512;
  // on|off (out of core; OutOfCoreSettings::prefetch). On: a moving view converges sooner (compare
  // with bench --path-kind zoom-in --prefetch on|off).
  std::string prefetch = "on";
  bool distributed = false;     // render, bench: sort-last under mpirun (apps/distributed.h)

  // Rendered through the page table and brick cache: --cache-mb, a procedural volume, or
  // --distributed (each rank's out-of-core renderer on its region).
  bool out_of_core() const;
};

// Registers the options above on `c` (those of `cmd`), with what `o` holds as the defaults.
void add_render_options(CLI::App& c, RenderOptions& o, Command cmd);

// The options checked before any (slow) data load.
struct CheckedOptions {
  RenderSettings settings;  // iso still the default: complete_settings sets it
  ListSource lists = ListSource::Cpu;
  CudaSampler cuda_sampler = CudaSampler::Slots;
};
CheckedOptions check_render_options(const RenderOptions& o);

// The share of the memory available (process_memory.h) a --cache-mb budget may take; more is refused
// naming the option and the memory available, before anything is loaded.
inline constexpr double kCacheShareOfAvailableMemory = 0.9;
void check_cache_budget(std::size_t cache_mb);

// What needs the loaded scene, the same in every command: labels mode needs a label volume (and out
// of core the set to show, --enable); the iso default depends on the data.
void complete_settings(const RenderOptions& o, const SourceScene& s, RenderSettings& rs);

// Whether a render with these options reads labels: labels mode, or an enabled-label mask (--enable).
inline bool shows_labels(const RenderOptions& o) { return o.mode == "labels" || !o.scene.enable.empty(); }

// The out-of-core renderer's settings from the options (cache 1024 MB when --cache-mb is not given).
OutOfCoreSettings out_of_core_settings(const RenderOptions& o);

// The methods out of core (the page-table sampler walks segment lists or every sample); also what the
// viewer's method keys and buttons offer there.
// --block auto: the culling block edge in core and out of core. In core 8: faster frames than 16 on
// sparse volumes, the same on dense ones (docs/skipping.md); out of core 16: it keeps the metadata of
// a brick, and so the cache's metadata budget, small.
inline constexpr int kInCoreBlock = 8;
inline constexpr int kOutOfCoreBlock = 16;
// The block edge `text` (auto, 4, 8, 16 or 32) names; throws InputError("--block", ...) otherwise.
int parse_block(const std::string& text, bool out_of_core);

inline bool out_of_core_method(SkipMethod m) { return m == SkipMethod::SparseLeap || m == SkipMethod::None; }

}  // namespace sl::app
