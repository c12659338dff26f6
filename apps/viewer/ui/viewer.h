// `sparseleap view`: the interactive window (DESIGN.md "Programs"). Options come from apps/view_cmd.cpp.
#pragma once

#include <string>

#include "apps/render_options.h"

namespace sl::viewer {

struct ViewerOptions {
  app::RenderOptions render;   // shared with render and bench (apps/render_options.h); --size is the canvas
  float scale = 1.0f;          // render resolution relative to the canvas
  std::string progressive = "on";  // on: coarse frames while the view changes (apps/viewer/progressive.h)
  double frame_budget_ms = 80.0;   // the time a coarse frame may take
  std::string path;            // scripted run: replay this camera path (core/scene/camera_path.h)
  std::string screenshot;      // save the window after `frames` frames, then exit
  int frames = 0;              // scripted run: render this many views, then exit
  float spin = 0.0f;           // scripted run: degrees of orbit per frame (times moving views)
  std::string record_path;     // camera path file (K adds keyframes; saved on exit)
  bool no_stats = false;
};

// Returns the exit code. Input errors throw InputError (caught in main); no display or GL context
// prints one line and returns 1.
int run_viewer(const ViewerOptions& o);

}  // namespace sl::viewer
