// The viewer's mouse and keys, read from ImGui's input state once per UI frame: orbit, pan and zoom
// on the canvas, a click toggling the label under the cursor, and the key bindings
// (apps/viewer/view_settings.h).
#pragma once

#include "apps/viewer/ui/panels.h"
#include "apps/viewer/ui/session.h"
#include "core/scene/volume.h"

namespace sl::viewer {

// Mouse gestures on the canvas (not over a panel).
struct Drag {
  // Seconds after the last wheel notch that still count as zooming.
  static constexpr double kWheelSettle = 0.25;

  int button = -1;  // 0 left, 1 right, 2 middle; -1 none
  float moved = 0.0f;
  double last_wheel = -1e9;

  // A button held or the wheel turned just now (`now`: ImGui's time).
  bool active(double now) const { return button >= 0 || now - last_wheel < kWheelSettle; }
};

// Left drag orbits, middle (or shift-left) drag pans, the wheel and right drag zoom, a left click
// picks a label of `labels` (null: no label volume) in the frame on screen.
void canvas_input(Session& s, Drag& d, const Volume* labels, const Shown& shown, const Canvas& c);

// Applies the view keys to s.view; returns what the viewer carries out (reset, screenshot, keyframe).
// Nothing while an ImGui widget has the keyboard.
PanelActions key_input(Session& s);

}  // namespace sl::viewer
