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
#include "apps/viewer/label_state.h"
#include "apps/viewer/orbit_controller.h"
#include "apps/viewer/path_recorder.h"
#include "apps/viewer/progressive.h"
#include "apps/viewer/render_worker.h"
#include "apps/viewer/screenshot.h"
#include "apps/viewer/stats_rows.h"
#include "apps/viewer/tf_editor.h"
#include "apps/viewer/ui/panels.h"
#include "apps/viewer/ui/window.h"
#include "core/scene/camera_path.h"
#include "core/util/error.h"
#include "core/util/parallel.h"

namespace sl::viewer {

namespace {

constexpr float kClickSlop = 3.0f;       // pixels a click may move and still be a click (label pick)
constexpr double kWheelSettle = 0.25;    // seconds after the last wheel notch that still count as zooming
constexpr int kSettleFrames = 3;         // UI frames before a scripted screenshot: auto-sized windows settle
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

// Everything the loop edits, in one place; the panels get pointers into it.
struct Session {
  ViewSettings view;
  std::optional<TfEditor> tf;
  std::vector<float> histogram;
  std::optional<LabelState> labels;
  std::optional<OrbitController> orbit;
  PathRecorder path;
  PanelState panel;
};

// The frame on screen: what picking casts through, what the overlay describes.
struct Shown {
  bool valid = false;
  Camera camera;
  int width = 0;
  int height = 0;
  int level = 0;  // progressive level of the frame on screen
  Stats stats;
  std::string error;
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

// Mouse gestures on the canvas (not over a panel).
struct Drag {
  int button = -1;  // 0 left, 1 right, 2 middle; -1 none
  float moved = 0.0f;
  double last_wheel = -1e9;
};

using ViewerScene = app::SourceScene;

// Options checked before the (possibly slow) data load, so a typo fails at once.
ViewSettings settings_from(const ViewerOptions& o, const app::CheckedOptions& checked) {
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

// Toggles the label under the cursor: the first visible label along the pixel's ray goes off; where
// no visible label is hit, the first hidden one along the ray comes back on.
void pick(Session& s, const ViewerScene& sc, const Shown& shown, float u, float v) {
  if (!s.labels || !sc.labels || !shown.valid) return;
  const Volume& labels = *sc.labels;
  LabelState& L = *s.labels;
  const int px = int(u * float(shown.width));
  const int py = int(v * float(shown.height));
  const bool masked = L.masking() || s.view.render.mode == RenderMode::Labels;
  std::uint32_t id = pick_label(labels, shown.camera, shown.width, shown.height, px, py,
                                masked ? &L.enabled() : nullptr);
  if (id == 0 && masked) id = pick_label(labels, shown.camera, shown.width, shown.height, px, py);
  if (id == 0) {
    s.panel.status = "no label under the cursor";
    return;
  }
  const bool was_visible = !masked || L.is_enabled(id);
  L.set_enabled(id, !was_visible);  // switches masking on: the toggle must show in dvr too
  s.panel.search_id = int(id);
  s.panel.status = "label " + std::to_string(id) + (was_visible ? " off" : " on");
}

void canvas_input(Session& s, Drag& d, const ViewerScene& sc, const Shown& shown, float x0, float w, float h,
                  float pixel_ratio) {
  ImGuiIO& io = ImGui::GetIO();
  const ImVec2 m = io.MousePos;
  const bool in_canvas = m.x >= x0 && m.x < x0 + w && m.y >= 0.0f && m.y < h;
  OrbitController& orbit = *s.orbit;
  if (!io.WantCaptureMouse && in_canvas) {
    for (int b = 0; b < 3 && d.button < 0; ++b) {
      if (ImGui::IsMouseClicked(b)) {
        d.button = b;
        d.moved = 0.0f;
      }
    }
    if (io.MouseWheel != 0.0f) {
      orbit.zoom(io.MouseWheel);
      d.last_wheel = ImGui::GetTime();
    }
  }
  if (d.button < 0) return;
  const ImVec2 delta = io.MouseDelta;
  d.moved += std::abs(delta.x) + std::abs(delta.y);
  if (delta.x != 0.0f || delta.y != 0.0f) {
    if (d.button == 2 || (d.button == 0 && io.KeyShift)) {
      orbit.pan(delta.x * pixel_ratio, delta.y * pixel_ratio, int(h * pixel_ratio));
    } else if (d.button == 0) {
      orbit.orbit(delta.x, delta.y);
    } else {
      orbit.zoom(-delta.y * 0.05f);  // right drag: zoom for mice without a wheel
    }
  }
  if (!io.MouseDown[d.button]) {
    if (d.button == 0 && d.moved < kClickSlop && !io.KeyShift) pick(s, sc, shown, (m.x - x0) / w, m.y / h);
    d.button = -1;
  }
}

PanelActions key_input(Session& s) {
  PanelActions a;
  if (ImGui::GetIO().WantCaptureKeyboard) return a;
  for (int key : {'1', '2', '3', '4', 'M', 'B', 'D', 'L', 'E', 'F', 'R', 'S', 'K'}) {
    if (!ImGui::IsKeyPressed(key, false)) continue;
    switch (apply_key(s.view, key)) {
      case KeyAction::ResetView: a.reset_view = true; break;
      case KeyAction::Screenshot: a.screenshot = true; break;
      case KeyAction::Keyframe: a.keyframe = true; break;
      default: break;
    }
  }
  return a;
}

void save_screenshot(Window& win, const std::string& path, PanelState& st) {
  int w = 0, h = 0;
  const std::vector<std::uint8_t> px = win.read_back(w, h);
  write_png_rgba8(path, w, h, px, /*bottom_up=*/true);
  st.status = "saved " + path;
  std::printf("view: saved %s (%dx%d)\n", path.c_str(), w, h);
  std::fflush(stdout);
}

}  // namespace

int run_viewer(const ViewerOptions& o) {
  // Everything that can be wrong with the input is checked before a window opens.
  const app::CheckedOptions checked = app::check_render_options(o.render);
  const ThreadLimit threads(o.render.threads);
  if (!o.screenshot.empty()) check_output_prefix(o.screenshot);
  if (!o.record_path.empty()) check_output_prefix(o.record_path);
  Session s;
  s.view = settings_from(o, checked);
  const std::optional<CameraPath> replay =
      o.path.empty() ? std::nullopt : std::optional<CameraPath>(load_camera_path(o.path));
  const ViewerScene sc = app::load_source_scene(o.render.scene, o.render.out_of_core());
  app::complete_settings(o.render, sc, s.view.render);  // same checks and iso default as `render`
  s.view.has_labels = sc.labels != nullptr;  // labels mode and picking need the label voxels
  s.view.out_of_core = sc.out_of_core();
  const int canvas_w = s.view.render.width;
  const int canvas_h = s.view.render.height;
  std::string backend_notice;
  const app::Backend backend = app::choose_backend(o.render.backend, &backend_notice);
  std::unique_ptr<Window> win;  // declared before the worker: destroyed after it, so no frame wakes a closed GLFW
  RenderWorker worker(sc.volume.get(), sc.labels.get(), make_renderer(sc, o, checked, backend), &Window::wake);
  float lo = 0.0f, hi = 255.0f;
  if (sc.volume) {
    data_domain(*sc.volume, lo, hi);
  } else if (sc.desc.type != VoxelType::U8) {
    lo = sc.tf.vmin();
    hi = sc.tf.vmax();
  }
  s.tf.emplace(sc.tf, lo, hi);
  // A procedural source has no voxels in memory to count: its editor shows no histogram.
  if (sc.volume) s.histogram = value_histogram(*sc.volume, kHistogramBins, s.tf->lo(), s.tf->hi());
  if (sc.labels) s.labels.emplace(sc.label_count, sc.enabled);
  s.orbit.emplace(sc.camera);
  if (!o.render.scene.tf.empty()) s.panel.tf_file = o.render.scene.tf;
  if (!o.record_path.empty()) s.panel.path_file = o.record_path;

  try {
    const std::string title = "sparseleap view: " + sc.name + (sc.out_of_core() ? " (out of core)" : "");
    win = std::make_unique<Window>(canvas_w + int(kPanelWidth), canvas_h, title);
  } catch (const WindowError& e) {
    std::fprintf(stderr, "sparseleap: error: view: %s\n", e.what());
    return 1;
  }
  if (!backend_notice.empty()) std::fputs(backend_notice.c_str(), stderr);  // all checks passed
  FrameTexture texture;

  const bool scripted = o.frames > 0 || !o.screenshot.empty() || replay.has_value();
  const int views_wanted = replay ? replay->frames : o.frames > 0 ? o.frames : 3;
  int views_submitted = 0, settle = kSettleFrames;
  bool in_flight = false;  // scripted runs: one job at a time, each a real frame
  std::uint64_t refine_id = 0;
  std::vector<FrameRecord> views;
  std::optional<FrameRecord> refined;
  ProgressiveLevels levels(s.view.frame_budget_ms);
  FrameRate rate;
  std::shared_ptr<const TransferFunction> tf_snap;
  std::uint64_t tf_rev = ~std::uint64_t(0);
  std::shared_ptr<const LabelSet> label_snap;
  std::uint64_t label_rev = ~std::uint64_t(0);
  std::optional<Wanted> last_wanted;
  int last_level = 0;  // of the last job submitted
  std::uint64_t next_id = 1;
  Shown shown;
  Drag drag;
  bool interacting = false;
  const auto clock_start = std::chrono::steady_clock::now();
  const auto seconds = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - clock_start).count();
  };

  const QuitSignals quit_signals;
  while (!win->should_close() && !g_quit) {
    const bool busy = !worker.idle();
    // The worker wakes the loop when a frame is done, so waiting long costs no latency; a short
    // timeout only while the user interacts keeps ImGui's own feedback smooth.
    win->begin_frame(interacting ? 0.016 : 0.1);
    ImGuiIO& io = ImGui::GetIO();

    if (std::optional<RenderResult> r = worker.take()) {
      const double now = seconds();
      in_flight = false;
      if (r->error.empty()) {
        texture.upload(r->width, r->height, r->rgba8);
        // Metadata is computed once and cached (DESIGN.md §3): it says nothing about later frames.
        levels.observe(r->level, r->worker_ms - r->stats.time_ms.metadata);
        rate.tick(now);
        const FrameRecord rec{r->level, r->stats.time_ms.total, now};
        if (scripted && r->id == refine_id) {
          refined = rec;
        } else if (scripted) {
          views.push_back(rec);
        }
        shown = Shown{true, r->camera, r->width, r->height, r->level, std::move(r->stats), {}};
      } else {
        shown.error = r->error;
        if (scripted) {
          std::fprintf(stderr, "sparseleap: error: view: %s\n", r->error.c_str());
          return 1;
        }
      }
    }

    const float win_w = io.DisplaySize.x, win_h = io.DisplaySize.y;
    const float ratio = win->pixel_ratio();
    const float x0 = kPanelWidth;
    const float cw = std::max(win_w - x0, 1.0f), ch = std::max(win_h, 1.0f);

    PanelModel model{&s.view, &*s.tf, &s.histogram, s.labels ? &*s.labels : nullptr, &s.path,
                     shown.valid ? &shown.stats : nullptr};
    PanelActions a = draw_control_panel(model, s.panel, kPanelWidth, win_h);
    if (!texture.empty()) {
      ImGui::GetBackgroundDrawList()->AddImage(texture.imgui_id(), ImVec2(x0, 0.0f), ImVec2(x0 + cw, ch));
    }
    {
      OverlayInfo info{io.Framerate, shown.width, shown.height, shown.level, busy,
                       shown.valid ? pending_loads(shown.stats) : 0, shown.error};
      std::vector<StatRow> rows;
      if (s.view.show_stats) {
        rows = stats_rows(shown.stats);
        for (StatRow& row : progressive_rows(s.view.progressive, shown.level, rate.fps(seconds()),
                                             s.view.frame_budget_ms)) {
          rows.push_back(std::move(row));
        }
      }
      draw_stats_overlay(rows, info, win_w, 0.0f, s.view.show_stats);
    }
    if (!scripted) canvas_input(s, drag, sc, shown, x0, cw, ch, ratio);
    const PanelActions keys = key_input(s);
    if (a.reset_view || keys.reset_view) s.orbit->reset();
    if (a.keyframe || keys.keyframe) {
      s.panel.status = s.path.add(s.orbit->camera()) ? "keyframe " + std::to_string(s.path.size())
                                                     : "keyframe unchanged: not added";
    }
    s.path.tick(ImGui::GetTime(), s.orbit->camera());
    if (a.save_path) {
      try {
        s.path.save(s.panel.path_file);
        s.panel.status = "saved " + s.panel.path_file + " (" + std::to_string(s.path.size()) + " keyframes)";
      } catch (const std::exception& e) {
        s.panel.status = e.what();
      }
    }

    // The frame wanted now: a changed view is rendered at the moving level first, the full-resolution
    // frame once it is still.
    if (s.tf->revision() != tf_rev) {
      tf_snap = std::make_shared<const TransferFunction>(s.tf->build());
      tf_rev = s.tf->revision();
    }
    if (s.labels && s.labels->revision() != label_rev) {
      label_snap = std::make_shared<const LabelSet>(s.labels->enabled());
      label_rev = s.labels->revision();
    }
    interacting = !scripted && (drag.button >= 0 || ImGui::GetTime() - drag.last_wheel < kWheelSettle || a.dragging);
    const auto wanted = [&](const Camera& camera) {
      Wanted w;
      w.camera = camera;
      w.settings = s.view.render;
      w.settings.width = std::max(1, int(std::lround(cw * ratio * s.view.scale)));
      w.settings.height = std::max(1, int(std::lround(ch * ratio * s.view.scale)));
      w.tf = tf_snap;
      // Labels mode always gets the set (else the renderer scans the label volume for "all" per frame).
      const bool use_labels = s.labels && (s.labels->masking() || w.settings.mode == RenderMode::Labels);
      w.enabled = use_labels ? label_snap : nullptr;
      return w;
    };
    const auto submit = [&](const Wanted& w, int level, std::uint64_t id) {
      worker.submit(job_at(w, level, id));
      last_wanted = w;
      last_level = level;
    };
    const auto moving_level = [&] { return s.view.progressive ? levels.moving_level() : 0; };
    if (scripted) {
      // Every view is one frame, so the run measures what a user orbiting at this rate sees; a view
      // that differs from the previous one is a moving frame. The last view is then refined.
      if (!in_flight && views_submitted < views_wanted) {
        if (!replay && views_submitted > 0 && o.spin != 0.0f) {
          s.orbit->orbit(o.spin * 3.14159265f / 180.0f / OrbitController::kRadiansPerPixel, 0.0f);
        }
        const Wanted w = wanted(replay ? replay->at(views_submitted) : s.orbit->camera());
        const bool moving = last_wanted && !same_wanted(w, *last_wanted);
        submit(w, moving ? moving_level() : 0, next_id++);
        ++views_submitted;
        in_flight = true;
      } else if (!in_flight && last_level > 0 && refine_id == 0) {
        refine_id = next_id++;
        submit(*last_wanted, 0, refine_id);
        in_flight = true;
      }
    } else {
      const Wanted w = wanted(s.orbit->camera());
      switch (next_submission(!last_wanted || !same_wanted(w, *last_wanted), interacting, last_level, worker.idle(),
                              shown.valid && shown.level == 0 && still_refining(shown.stats))) {
        case Submission::Changed: submit(w, moving_level(), next_id++); break;
        case Submission::Refine:
        case Submission::Repeat: submit(w, 0, next_id++); break;
        case Submission::None: break;
      }
    }

    win->end_frame();
    if (a.screenshot || keys.screenshot) {
      try {
        save_screenshot(*win, next_screenshot_name("."), s.panel);
      } catch (const std::exception& e) {
        s.panel.status = e.what();
      }
    }
    if (scripted && int(views.size()) >= views_wanted && !in_flight && last_level == 0 && --settle <= 0) {
      if (!o.screenshot.empty()) save_screenshot(*win, o.screenshot, s.panel);
      break;
    }
    win->swap();
  }
  if (!o.record_path.empty() && s.path.size() > 0) {
    s.path.save(o.record_path);
    std::printf("view: saved %s (%zu keyframes)\n", o.record_path.c_str(), s.path.size());
  }
  report(views, refined, shown);
  return 0;
}

}  // namespace sl::viewer
