// The viewer's ImGui panels: controls (method, mode, b-box, depth complexity, step, iso, transfer
// function, labels, camera path) and the stats overlay. Drawing only: every edit goes through the
// plain state classes (TfEditor, LabelState, PathRecorder, ViewSettings) that tests exercise.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "apps/viewer/label_state.h"
#include "apps/viewer/path_recorder.h"
#include "apps/viewer/stats_rows.h"
#include "apps/viewer/tf_editor.h"
#include "apps/viewer/view_settings.h"

namespace sl::viewer {

// What the panels edit; owned by the viewer loop.
struct PanelModel {
  ViewSettings* view = nullptr;
  TfEditor* tf = nullptr;
  const std::vector<float>* histogram = nullptr;
  LabelState* labels = nullptr;  // null without a label volume
  PathRecorder* path = nullptr;
  const Stats* stats = nullptr;  // last finished frame (null before the first)
};

// Widget state that lives across UI frames.
struct PanelState {
  int tf_selected = -1;
  int tf_dragging = -1;
  std::string tf_file = "transfer_function.json";
  std::string path_file = "sparseleap-path.json";
  int search_id = 1;
  float fraction = 0.5f;
  std::uint64_t fraction_seed = 1;
  float keyframe_interval = 1.0f;
  bool keyframe_timer = false;
  std::string status;  // last message (saved file, error), shown at the bottom of the panel
};

// Buttons whose effect the viewer loop carries out.
struct PanelActions {
  bool reset_view = false;
  bool screenshot = false;
  bool keyframe = false;
  bool save_path = false;
  bool dragging = false;  // a transfer-function point is being dragged: render coarse frames
};

// The control panel fills the window's left strip [0, width) x [0, height) (window units).
PanelActions draw_control_panel(PanelModel& m, PanelState& st, float width, float height);

// Extra lines for the overlay beside the frame's Stats (UI rate, coarse level, pending loads, errors).
struct OverlayInfo {
  float ui_fps = 0.0f;
  int render_width = 0;
  int render_height = 0;
  int level = 0;  // progressive level of the frame on screen (0: full resolution)
  bool rendering = false;
  std::uint64_t pending_loads = 0;
  std::string error;
};

// Semi-transparent window in the canvas's top-right corner (`right`, `top` in window units). With
// `full` off (stats hidden) only the loading indicator and errors show, and nothing when neither.
void draw_stats_overlay(const std::vector<StatRow>& rows, const OverlayInfo& info, float right, float top,
                        bool full = true);

// Panel width in window units (the canvas starts there).
constexpr float kPanelWidth = 330.0f;

}  // namespace sl::viewer
