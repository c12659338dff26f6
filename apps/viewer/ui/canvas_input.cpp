#include "apps/viewer/ui/canvas_input.h"

#include <imgui.h>

#include <cmath>
#include <cstdint>
#include <string>

namespace sl::viewer {

namespace {

constexpr float kClickSlop = 3.0f;  // pixels a click may move and still be a click (label pick)

// Toggles the label under the cursor: the first visible label along the pixel's ray goes off; where
// no visible label is hit, the first hidden one along the ray comes back on.
void pick(Session& s, const Volume* labels, const Shown& shown, float u, float v) {
  if (!s.labels || !labels || !shown.valid) return;
  LabelState& L = *s.labels;
  const int px = int(u * float(shown.width));
  const int py = int(v * float(shown.height));
  const bool masked = L.masking() || s.view.render.mode == RenderMode::Labels;
  std::uint32_t id = pick_label(*labels, shown.camera, shown.width, shown.height, px, py,
                                masked ? &L.enabled() : nullptr);
  if (id == 0 && masked) id = pick_label(*labels, shown.camera, shown.width, shown.height, px, py);
  if (id == 0) {
    s.panel.status = "no label under the cursor";
    return;
  }
  const bool was_visible = !masked || L.is_enabled(id);
  L.set_enabled(id, !was_visible);  // switches masking on: the toggle must show in dvr too
  s.panel.search_id = int(id);
  s.panel.status = "label " + std::to_string(id) + (was_visible ? " off" : " on");
}

// A press or a wheel notch over the canvas (not over a panel) starts a gesture.
void start_gesture(OrbitController& orbit, Drag& d, const Canvas& c) {
  const ImGuiIO& io = ImGui::GetIO();
  const ImVec2 m = io.MousePos;
  const bool in_canvas = m.x >= c.x0 && m.x < c.x0 + c.w && m.y >= 0.0f && m.y < c.h;
  if (io.WantCaptureMouse || !in_canvas) return;
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

void drag_camera(OrbitController& orbit, const Drag& d, ImVec2 delta, const Canvas& c) {
  if (delta.x == 0.0f && delta.y == 0.0f) return;
  if (d.button == 2 || (d.button == 0 && ImGui::GetIO().KeyShift)) {
    orbit.pan(delta.x * c.pixel_ratio, delta.y * c.pixel_ratio, int(c.h * c.pixel_ratio));
  } else if (d.button == 0) {
    orbit.orbit(delta.x, delta.y);
  } else {
    orbit.zoom(-delta.y * 0.05f);  // right drag: zoom for mice without a wheel
  }
}

}  // namespace

void canvas_input(Session& s, Drag& d, const Volume* labels, const Shown& shown, const Canvas& c) {
  const ImGuiIO& io = ImGui::GetIO();
  start_gesture(*s.orbit, d, c);
  if (d.button < 0) return;
  const ImVec2 delta = io.MouseDelta;
  d.moved += std::abs(delta.x) + std::abs(delta.y);
  drag_camera(*s.orbit, d, delta, c);
  if (!io.MouseDown[d.button]) {
    const ImVec2 m = io.MousePos;
    if (d.button == 0 && d.moved < kClickSlop && !io.KeyShift) pick(s, labels, shown, (m.x - c.x0) / c.w, m.y / c.h);
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

}  // namespace sl::viewer
