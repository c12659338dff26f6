// What the viewer loop keeps between UI frames: the state the panels and the input edit, and the
// frame on screen.
#pragma once

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "apps/viewer/label_state.h"
#include "apps/viewer/orbit_controller.h"
#include "apps/viewer/path_recorder.h"
#include "apps/viewer/tf_editor.h"
#include "apps/viewer/ui/panels.h"
#include "apps/viewer/view_settings.h"
#include "core/frame/frame.h"

namespace sl::viewer {

// Everything the loop edits, in one place; the panels get pointers into it.
struct Session {
  explicit Session(ViewSettings v) : view(std::move(v)) {}
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

// Where the frame is drawn this UI frame (window units), and framebuffer pixels per window unit.
struct Canvas {
  float window_w = 0.0f, window_h = 0.0f;
  float x0 = kPanelWidth;  // the canvas starts right of the control panel
  float w = 1.0f, h = 1.0f;
  float pixel_ratio = 1.0f;
};

}  // namespace sl::viewer
