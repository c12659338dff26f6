// The viewer's loop: input -> plain state -> a render job for the worker thread -> the finished frame
// as a texture behind the ImGui panels. The UI thread never renders, so input stays live during a
// long frame; while the view changes, frames are rendered at a coarse level that holds the frame budget
// and the full-resolution frame follows once the view is still (progressive rendering,
// apps/viewer/progressive.h).
#include "apps/viewer/ui/viewer.h"

#include <imgui.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <memory>
#include <optional>

#include "apps/scene_renderer.h"
#include "apps/viewer/progressive.h"
#include "apps/viewer/render_worker.h"
#include "apps/viewer/screenshot.h"
#include "apps/viewer/stats_rows.h"
#include "apps/viewer/ui/canvas_input.h"
#include "apps/viewer/ui/panels.h"
#include "apps/viewer/ui/session.h"
#include "apps/viewer/ui/window.h"
#include "core/scene/camera_path.h"
#include "core/util/error.h"
#include "core/util/parallel.h"

namespace sl::viewer {

namespace {

constexpr int kSettleFrames = 3;  // UI frames before a scripted screenshot: auto-sized windows settle
constexpr int kHistogramBins = 128;

// Ctrl-C (or a SIGTERM) ends the loop normally, so a recorded camera path is still saved.
std::atomic<bool> g_quit{false};
extern "C" void on_quit_signal(int) { g_quit = true; }

struct QuitSignals {
  QuitSignals() {
    g_quit = false;
    std::signal(SIGINT, on_quit_signal);
    std::signal(SIGTERM, on_quit_signal);
  }
  ~QuitSignals() {
    std::signal(SIGINT, SIG_DFL);
    std::signal(SIGTERM, SIG_DFL);
  }
};

// What the viewer wants rendered, apart from the resolution: when it differs from the last request,
// the view is changing and a coarse frame comes first.
struct Wanted {
  Camera camera;
  RenderSettings settings;  // at full resolution
  std::shared_ptr<const TransferFunction> tf;
  std::shared_ptr<const LabelSet> enabled;
};

bool same_wanted(const Wanted& a, const Wanted& b) {
  return same_camera(a.camera, b.camera) && same_settings(a.settings, b.settings) && a.tf == b.tf &&
         a.enabled == b.enabled;
}

RenderJob job_at(const Wanted& w, int level, std::uint64_t id) {
  RenderJob job;
  job.id = id;
  job.camera = w.camera;
  job.settings = w.settings;
  job.settings.width = level_extent(w.settings.width, level);
  job.settings.height = level_extent(w.settings.height, level);
  job.tf = w.tf;
  job.enabled = w.enabled;
  job.level = level;
  return job;
}

// A scripted run's frames: the views (frame 0 the start-up frame, then every new view one frame),
// and the refinement of the last view when it was shown coarse.
struct FrameRecord {
  int level = 0;
  double total_ms = 0.0;
  double shown_at = 0.0;  // seconds since the loop started, when the frame reached the screen
};

using ViewerScene = app::SourceScene;

// Options checked before the (possibly slow) data load, so a typo fails at once.
ViewSettings settings_from(const ViewerOptions& o, const app::CheckedOptions& checked) {
  if (!o.screenshot.empty()) check_output_prefix(o.screenshot);
  if (!o.record_path.empty()) check_output_prefix(o.record_path);
  ViewSettings v;
  v.render = checked.settings;
  if (!(o.scale > 0.0f && o.scale <= 1.0f)) throw InputError("--scale", "must be in (0, 1]");
  if (o.progressive != "on" && o.progressive != "off") throw InputError("--progressive", "must be on or off");
  if (!(o.frame_budget_ms >= 1.0 && o.frame_budget_ms <= 10000.0)) {
    throw InputError("--frame-budget-ms", "must be between 1 and 10000");
  }
  if (o.frames < 0 || o.frames > 100000) throw InputError("--frames", "must be between 0 and 100000");
  if (!std::isfinite(o.spin)) throw InputError("--spin", "must be a number of degrees");
  if (!o.path.empty() && (o.frames > 0 || o.spin != 0.0f)) {
    throw InputError("--path", "sets the views itself: not with --frames or --spin");
  }
  v.scale = o.scale;
  v.progressive = o.progressive == "on";
  v.frame_budget_ms = o.frame_budget_ms;
  v.show_stats = !o.no_stats;
  return v;
}

// The renderer is made on the render worker's thread (RenderWorker): a GL list builder's context
// must be current where it renders.
std::function<RenderWorker::RenderFn()> make_renderer(const ViewerScene& sc, const ViewerOptions& o,
                                                      const app::CheckedOptions& checked, app::Backend backend) {
  return [&sc, &o, checked, backend] {
    auto r = std::make_shared<app::SceneRenderer>(sc, o.render, checked, backend);
    // The worker's Scene carries the snapshots (tf, labels, camera); the data come from the scene.
    // Out of core with --prefetch on, the next view is extrapolated from the last two the worker
    // rendered (prefetch along the camera's motion; a still camera extrapolates to itself).
    auto last = std::make_shared<std::optional<Camera>>();
    return RenderWorker::RenderFn([r, last](const Scene& s, const RenderSettings& rs) {
      const std::optional<Camera> prev = *last;
      *last = s.camera;
      if (!prev) return r->render(*s.tf, s.enabled, s.camera, rs);
      const Camera next = extrapolate_camera(*prev, s.camera);
      return r->render(*s.tf, s.enabled, s.camera, rs, &next);
    });
  };
}

// One line for scripts: the views' frame times, the rate at which views 1.. reached the screen (frame
// 0 is the start-up frame: metadata, first lists) and their pixel levels, then the refinement.
void report(const std::vector<FrameRecord>& views, const std::optional<FrameRecord>& refined, const Shown& shown) {
  if (views.empty() || !shown.valid) return;
  std::printf("view: %zu frames, first %.1f ms", views.size(), views[0].total_ms);
  if (views.size() > 1) {
    double sum = 0.0;
    int finest = kCoarsestLevel, coarsest = 0;
    for (std::size_t i = 1; i < views.size(); ++i) {
      sum += views[i].total_ms;
      finest = std::min(finest, views[i].level);
      coarsest = std::max(coarsest, views[i].level);
    }
    const double n = double(views.size() - 1);
    const double span = views.back().shown_at - views[0].shown_at;
    std::printf(", then %.1f ms mean, %.1f frames/s, pixels %s", sum / n, span > 0.0 ? n / span : 0.0,
                level_label(coarsest).c_str());
    if (finest != coarsest) std::printf(" to %s", level_label(finest).c_str());
  }
  if (refined) std::printf("; refined in %.1f ms", refined->total_ms);
  std::printf("; last: %s\n", stats_summary(shown.stats).c_str());
}

void save_screenshot(Window& win, const std::string& path, PanelState& st) {
  int w = 0, h = 0;
  const std::vector<std::uint8_t> px = win.read_back(w, h);
  write_png_rgba8(path, w, h, px, /*bottom_up=*/true);
  st.status = "saved " + path;
  std::printf("view: saved %s (%dx%d)\n", path.c_str(), w, h);
  std::fflush(stdout);
}

// A scripted run (--frames, --screenshot, --path): a fixed number of views, one job at a time so each
// is a real frame, then the refinement of the last view when it was coarse, then exit.
struct Script {
  bool on = false;
  int views_wanted = 0;
  int views_submitted = 0;
  int settle = kSettleFrames;
  bool in_flight = false;
  std::uint64_t refine_id = 0;  // the refinement's job (0: not submitted)
  std::vector<FrameRecord> views;
  std::optional<FrameRecord> refined;
};

// What was handed to the render worker: snapshots of the edited transfer function and label set
// (rebuilt only when their revision changes) and the last request.
struct Requests {
  std::shared_ptr<const TransferFunction> tf;
  std::uint64_t tf_rev = ~std::uint64_t(0);
  std::shared_ptr<const LabelSet> labels;
  std::uint64_t label_rev = ~std::uint64_t(0);
  std::optional<Wanted> last_wanted;
  int last_level = 0;  // of the last job submitted
  std::uint64_t next_id = 1;
};

// The viewer: set up (options, data, render worker, then the window), then a loop of UI frames, each
// receiving the worker's newest frame, presenting it with the panels, taking input, and submitting
// the frame wanted next.
class Viewer {
 public:
  // Everything that can be wrong with the input is checked (InputError) before a window opens.
  explicit Viewer(const ViewerOptions& o);
  // False, having said why, when no window can open (no display, no GL context).
  bool open_window();
  // Runs until the window closes, Ctrl-C, or a scripted run ends; returns the exit code.
  int run();

 private:
  void init_editors();
  bool receive();
  Canvas canvas() const;
  PanelActions present(const Canvas& c, bool busy);
  void draw_overlay(const Canvas& c, bool busy);
  PanelActions input(const Canvas& c, PanelActions a);
  void save_path();
  void submit(const Canvas& c);
  void submit_scripted(const Canvas& c);
  void submit_interactive(const Canvas& c);
  Wanted wanted(const Camera& camera, const Canvas& c) const;
  void send(const Wanted& w, int level, std::uint64_t id);
  int moving_level() const { return s_.view.progressive ? levels_.moving_level() : 0; }
  bool end_ui_frame(const PanelActions& a);
  bool script_done();
  void finish();
  double seconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - clock_start_).count();
  }

  const ViewerOptions& o_;
  const app::CheckedOptions checked_;
  const ThreadLimit threads_;
  Session s_;
  const std::optional<CameraPath> replay_;
  const ViewerScene scene_;
  std::string backend_notice_;  // printed once the window is open: bad input stays one line
  app::Backend backend_ = app::Backend::Cpu;
  std::unique_ptr<Window> win_;  // declared before the worker: destroyed after it, so no frame wakes a closed GLFW
  std::optional<RenderWorker> worker_;  // started once the settings are complete
  FrameTexture texture_;  // declared after the window: its GL texture is deleted while the context lives
  Script script_;
  ProgressiveLevels levels_;
  FrameRate rate_;
  Requests req_;
  Shown shown_;
  Drag drag_;
  bool interacting_ = false;
  std::chrono::steady_clock::time_point clock_start_;
};

Viewer::Viewer(const ViewerOptions& o)
    : o_(o),
      checked_(app::check_render_options(o.render)),
      threads_(o.render.threads),
      s_(settings_from(o, checked_)),
      replay_(o.path.empty() ? std::nullopt : std::optional<CameraPath>(load_camera_path(o.path))),
      scene_(app::load_source_scene(o.render.scene, o.render.out_of_core(), true)),
      levels_(s_.view.frame_budget_ms) {
  app::complete_settings(o.render, scene_, s_.view.render);  // same checks and iso default as `render`
  s_.view.has_labels = scene_.labels != nullptr;  // labels mode and picking need the label voxels
  s_.view.out_of_core = scene_.out_of_core();
  backend_ = app::choose_backend(o.render.backend, &backend_notice_);
  worker_.emplace(scene_.volume.get(), scene_.labels.get(), make_renderer(scene_, o, checked_, backend_),
                  &Window::wake);
  init_editors();
  script_.on = o.frames > 0 || !o.screenshot.empty() || replay_.has_value();
  script_.views_wanted = replay_ ? replay_->frames : o.frames > 0 ? o.frames : 3;
}

void Viewer::init_editors() {
  float lo = 0.0f, hi = 255.0f;
  if (scene_.volume) {
    data_domain(*scene_.volume, lo, hi);
  } else if (scene_.desc.type != VoxelType::U8) {
    lo = scene_.tf.vmin();
    hi = scene_.tf.vmax();
  }
  s_.tf.emplace(scene_.tf, lo, hi);
  // A procedural source has no voxels in memory to count: its editor shows no histogram.
  if (scene_.volume) s_.histogram = value_histogram(*scene_.volume, kHistogramBins, s_.tf->lo(), s_.tf->hi());
  if (scene_.labels) s_.labels.emplace(scene_.label_count, scene_.enabled);
  s_.orbit.emplace(scene_.camera);
  if (!o_.render.scene.tf.empty()) s_.panel.tf_file = o_.render.scene.tf;
  if (!o_.record_path.empty()) s_.panel.path_file = o_.record_path;
}

bool Viewer::open_window() {
  try {
    const std::string title = "sparseleap view: " + scene_.name + (scene_.out_of_core() ? " (out of core)" : "");
    win_ = std::make_unique<Window>(s_.view.render.width + int(kPanelWidth), s_.view.render.height, title);
  } catch (const WindowError& e) {
    std::fprintf(stderr, "sparseleap: error: view: %s\n", e.what());
    return false;
  }
  if (!backend_notice_.empty()) std::fputs(backend_notice_.c_str(), stderr);  // all checks passed
  return true;
}

int Viewer::run() {
  clock_start_ = std::chrono::steady_clock::now();
  const QuitSignals quit_signals;
  while (!win_->should_close() && !g_quit) {
    const bool busy = !worker_->idle();
    // The worker wakes the loop when a frame is done, so waiting long costs no latency; a short
    // timeout only while the user interacts keeps ImGui's own feedback smooth.
    win_->begin_frame(interacting_ ? 0.016 : 0.1);
    if (!receive()) return 1;
    const Canvas c = canvas();
    // The panels come first: ImGui reports their buttons as it draws them, and the canvas takes only
    // the mouse input the panels leave.
    const PanelActions actions = input(c, present(c, busy));
    submit(c);
    if (!end_ui_frame(actions)) break;
  }
  finish();
  return 0;
}

// The worker's newest frame, if one finished: onto the texture, into the frame-time model and the
// scripted run's records. False when a scripted run's frame failed (the error is printed).
bool Viewer::receive() {
  std::optional<RenderResult> r = worker_->take();
  if (!r) return true;
  const double now = seconds();
  script_.in_flight = false;
  if (!r->error.empty()) {
    shown_.error = r->error;
    if (!script_.on) return true;
    std::fprintf(stderr, "sparseleap: error: view: %s\n", r->error.c_str());
    return false;
  }
  texture_.upload(r->width, r->height, r->rgba8);
  // Metadata is computed once and cached (DESIGN.md "Data model"): it says nothing about later frames.
  levels_.observe(r->level, r->worker_ms - r->stats.time_ms.metadata);
  rate_.tick(now);
  const FrameRecord rec{r->level, r->stats.time_ms.total, now};
  if (script_.on && r->id == script_.refine_id) {
    script_.refined = rec;
  } else if (script_.on) {
    script_.views.push_back(rec);
  }
  shown_ = Shown{true, r->camera, r->width, r->height, r->level, std::move(r->stats), {}};
  return true;
}

Canvas Viewer::canvas() const {
  const ImGuiIO& io = ImGui::GetIO();
  Canvas c;
  c.window_w = io.DisplaySize.x;
  c.window_h = io.DisplaySize.y;
  c.pixel_ratio = win_->pixel_ratio();
  c.w = std::max(c.window_w - c.x0, 1.0f);
  c.h = std::max(c.window_h, 1.0f);
  return c;
}

// The control panel, the frame on screen stretched over the canvas, the stats overlay; returns the
// panel's buttons.
PanelActions Viewer::present(const Canvas& c, bool busy) {
  PanelModel model{&s_.view, &*s_.tf, &s_.histogram, s_.labels ? &*s_.labels : nullptr, &s_.path,
                   shown_.valid ? &shown_.stats : nullptr};
  const PanelActions a = draw_control_panel(model, s_.panel, kPanelWidth, c.window_h);
  if (!texture_.empty()) {
    ImGui::GetBackgroundDrawList()->AddImage(texture_.imgui_id(), ImVec2(c.x0, 0.0f), ImVec2(c.x0 + c.w, c.h));
  }
  draw_overlay(c, busy);
  return a;
}

void Viewer::draw_overlay(const Canvas& c, bool busy) {
  OverlayInfo info{ImGui::GetIO().Framerate, shown_.width, shown_.height, shown_.level, busy,
                   shown_.valid ? pending_loads(shown_.stats) : 0, shown_.error};
  std::vector<StatRow> rows;
  if (s_.view.show_stats) {
    rows = stats_rows(shown_.stats);
    for (StatRow& row : progressive_rows(s_.view.progressive, shown_.level, rate_.fps(seconds()),
                                         s_.view.frame_budget_ms)) {
      rows.push_back(std::move(row));
    }
  }
  draw_stats_overlay(rows, info, c.window_w, 0.0f, s_.view.show_stats);
}

// Mouse on the canvas (interactive runs), keys, and what the panel's buttons and the keys ask for.
// Returns the panel's actions with the keys' added.
PanelActions Viewer::input(const Canvas& c, PanelActions a) {
  if (!script_.on) canvas_input(s_, drag_, scene_.labels.get(), shown_, c);
  const PanelActions keys = key_input(s_);
  a.reset_view = a.reset_view || keys.reset_view;
  a.keyframe = a.keyframe || keys.keyframe;
  a.screenshot = a.screenshot || keys.screenshot;
  if (a.reset_view) s_.orbit->reset();
  if (a.keyframe) {
    s_.panel.status = s_.path.add(s_.orbit->camera()) ? "keyframe " + std::to_string(s_.path.size())
                                                      : "keyframe unchanged: not added";
  }
  s_.path.tick(ImGui::GetTime(), s_.orbit->camera());
  if (a.save_path) save_path();
  interacting_ = !script_.on && (drag_.active(ImGui::GetTime()) || a.dragging);
  return a;
}

void Viewer::save_path() {
  try {
    s_.path.save(s_.panel.path_file);
    s_.panel.status = "saved " + s_.panel.path_file + " (" + std::to_string(s_.path.size()) + " keyframes)";
  } catch (const std::exception& e) {
    s_.panel.status = e.what();
  }
}

// The frame wanted now: a changed view is rendered at the moving level first, the full-resolution
// frame once it is still.
void Viewer::submit(const Canvas& c) {
  if (s_.tf->revision() != req_.tf_rev) {
    req_.tf = std::make_shared<const TransferFunction>(s_.tf->build());
    req_.tf_rev = s_.tf->revision();
  }
  if (s_.labels && s_.labels->revision() != req_.label_rev) {
    req_.labels = std::make_shared<const LabelSet>(s_.labels->enabled());
    req_.label_rev = s_.labels->revision();
  }
  if (script_.on) {
    submit_scripted(c);
  } else {
    submit_interactive(c);
  }
}

// Every view is one frame, so the run measures what a user orbiting at this rate sees; a view that
// differs from the previous one is a moving frame. The last view is then refined.
void Viewer::submit_scripted(const Canvas& c) {
  if (script_.in_flight) return;
  if (script_.views_submitted < script_.views_wanted) {
    if (!replay_ && script_.views_submitted > 0 && o_.spin != 0.0f) {
      s_.orbit->orbit(o_.spin * 3.14159265f / 180.0f / OrbitController::kRadiansPerPixel, 0.0f);
    }
    const Wanted w = wanted(replay_ ? replay_->at(script_.views_submitted) : s_.orbit->camera(), c);
    const bool moving = req_.last_wanted && !same_wanted(w, *req_.last_wanted);
    send(w, moving ? moving_level() : 0, req_.next_id++);
    ++script_.views_submitted;
    script_.in_flight = true;
  } else if (req_.last_level > 0 && script_.refine_id == 0) {
    script_.refine_id = req_.next_id++;
    send(*req_.last_wanted, 0, script_.refine_id);
    script_.in_flight = true;
  }
}

void Viewer::submit_interactive(const Canvas& c) {
  const Wanted w = wanted(s_.orbit->camera(), c);
  const bool changed = !req_.last_wanted || !same_wanted(w, *req_.last_wanted);
  const bool still_loading = shown_.valid && shown_.level == 0 && still_refining(shown_.stats);
  switch (next_submission(changed, interacting_, req_.last_level, worker_->idle(), still_loading)) {
    case Submission::Changed: send(w, moving_level(), req_.next_id++); break;
    case Submission::Refine:
    case Submission::Repeat: send(w, 0, req_.next_id++); break;
    case Submission::None: break;
  }
}

Wanted Viewer::wanted(const Camera& camera, const Canvas& c) const {
  Wanted w;
  w.camera = camera;
  w.settings = s_.view.render;
  w.settings.width = std::max(1, int(std::lround(c.w * c.pixel_ratio * s_.view.scale)));
  w.settings.height = std::max(1, int(std::lround(c.h * c.pixel_ratio * s_.view.scale)));
  w.tf = req_.tf;
  // Labels mode always gets the set (else the renderer scans the label volume for "all" per frame).
  const bool use_labels = s_.labels && (s_.labels->masking() || w.settings.mode == RenderMode::Labels);
  w.enabled = use_labels ? req_.labels : nullptr;
  return w;
}

void Viewer::send(const Wanted& w, int level, std::uint64_t id) {
  worker_->submit(job_at(w, level, id));
  req_.last_wanted = w;
  req_.last_level = level;
}

// Draws the UI and saves the screenshots asked for. False ends the loop: a scripted run is done (its
// screenshot saved); else the window is shown and the loop goes on.
bool Viewer::end_ui_frame(const PanelActions& a) {
  win_->end_frame();
  if (a.screenshot) {
    try {
      save_screenshot(*win_, next_screenshot_name("."), s_.panel);
    } catch (const std::exception& e) {
      s_.panel.status = e.what();
    }
  }
  if (script_done()) {
    if (!o_.screenshot.empty()) save_screenshot(*win_, o_.screenshot, s_.panel);
    return false;
  }
  win_->swap();
  return true;
}

// Every view shown at full resolution, and a few more UI frames so auto-sized windows settle.
bool Viewer::script_done() {
  return script_.on && int(script_.views.size()) >= script_.views_wanted && !script_.in_flight &&
         req_.last_level == 0 && --script_.settle <= 0;
}

void Viewer::finish() {
  if (!o_.record_path.empty() && s_.path.size() > 0) {
    s_.path.save(o_.record_path);
    std::printf("view: saved %s (%zu keyframes)\n", o_.record_path.c_str(), s_.path.size());
  }
  report(script_.views, script_.refined, shown_);
}

}  // namespace

int run_viewer(const ViewerOptions& o) {
  Viewer viewer(o);
  if (!viewer.open_window()) return 1;
  return viewer.run();
}

}  // namespace sl::viewer
