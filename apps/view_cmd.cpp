// `sparseleap view`: the interactive viewer (apps/viewer/). Built when GLFW, OpenGL and Dear ImGui
// are found (SL_VIEWER); otherwise the subcommand still exists and says what the build lacks.
#include <cstdio>
#include <memory>

#include "apps/commands.h"
#include "apps/render_options.h"
#ifdef SL_HAVE_VIEWER
#include "apps/viewer/ui/viewer.h"
#endif

namespace sl::app {

#ifdef SL_HAVE_VIEWER

Runner add_view_command(CLI::App& app) {
  auto o = std::make_shared<viewer::ViewerOptions>();
  CLI::App* c = app.add_subcommand(
      "view", "Interactive window: orbit/pan/zoom, method and mode switches, b-box and depth-complexity views, "
              "transfer-function and label editing, stats, camera-path recording");
  o->render.size = "800x600";
  add_render_options(*c, o->render, Command::View);
  c->add_option("--scale", o->scale, "Render resolution relative to the canvas, (0, 1]")->capture_default_str();
  c->add_option("--progressive", o->progressive,
                 "on: while the view changes render coarse frames that hold --frame-budget-ms, full resolution "
                 "once it is still; off: every frame at full resolution")
      ->capture_default_str();
  c->add_option("--frame-budget-ms", o->frame_budget_ms, "Time a coarse frame may take (1-10000 ms)")
      ->capture_default_str();
  c->add_option("--path", o->path,
                "Scripted run: replay this camera path (`bench --path` format), one view per frame, then refine "
                "the last view and exit; prints frames/s");
  c->add_option("--screenshot", o->screenshot, "Save the window (with the UI) to this PNG after --frames frames, then exit");
  c->add_option("--frames", o->frames, "Render this many views, then exit (default 3 with --screenshot)");
  c->add_option("--spin", o->spin, "Scripted runs: orbit this many degrees per frame (times moving views)");
  c->add_option("--record-path", o->record_path, "Camera-path JSON for `bench --path`: K adds a keyframe; saved on exit");
  c->add_flag("--no-stats", o->no_stats, "Start with the stats overlay hidden");
  return [o] { return viewer::run_viewer(*o); };
}

#else

Runner add_view_command(CLI::App& app) {
  CLI::App* c = app.add_subcommand("view", "Interactive window (not in this build: needs GLFW, OpenGL and Dear ImGui)");
  c->allow_extras();
  return [] {
    std::fprintf(stderr,
                 "sparseleap: error: view: this build has no viewer (GLFW, OpenGL or Dear ImGui was not found; "
                 "install libglfw3-dev libgl-dev libimgui-dev and reconfigure)\n");
    return 1;
  };
}

#endif

}  // namespace sl::app
