// `sparseleap view`: the interactive window (DESIGN.md §9). Options come from apps/view_cmd.cpp.
#pragma once

#include <cmath>
#include <string>

#include "apps/scene_loader.h"

namespace sl::viewer {

struct ViewerOptions {
  app::SceneOptions scene;
  std::string size = "800x600";  // the rendered canvas; the window adds the control panel
  std::string method = "sparseleap";
  std::string mode = "dvr";
  std::string view = "image";  // or depth-complexity
  bool boxes = false;
  std::string backend = "auto";
  std::size_t cache_mb = 0;    // > 0: out of core with this brick-cache budget (procedural: 1024)
  int brick = 32;              // out of core: brick payload edge
  float lod_bias = 1.0f;       // out of core: > 1 coarser levels
  float iso = NAN;
  float step = 0.5f;
  int block = 16;
  bool ert = false;
  float scale = 1.0f;          // render resolution relative to the canvas
  float preview_scale = 0.5f;  // while dragging
  std::string screenshot;      // save the window after `frames` frames, then exit
  int frames = 0;              // scripted run: render this many frames, then exit
  float spin = 0.0f;           // scripted run: degrees of orbit per frame (times moving views)
  std::string record_path;     // camera path file (K adds keyframes; saved on exit)
  bool no_stats = false;
  int threads = 0;
};

// Returns the exit code. Input errors throw InputError (caught in main); no display or GL context
// prints one line and returns 1.
int run_viewer(const ViewerOptions& o);

}  // namespace sl::viewer
