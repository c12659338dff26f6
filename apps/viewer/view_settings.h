// What the viewer renders, apart from the camera, transfer function and labels: the method and mode
// switches the panels and keys change, and the key bindings as a pure function (tested without a
// window). GLFW's key codes for letters and digits are their ASCII upper-case characters, so this
// file needs no GLFW header.
#pragma once

#include <type_traits>

#include "core/frame/frame.h"

namespace sl::viewer {

struct ViewSettings {
  RenderSettings render;       // width/height are set per frame from the canvas
  float scale = 1.0f;          // render resolution relative to the canvas (lower = faster)
  bool progressive = true;     // coarse frames while the view changes, full resolution once still
  double frame_budget_ms = 80.0;  // what a coarse frame may take (apps/viewer/progressive.h)
  bool has_labels = false;     // labels mode needs a label volume
  bool out_of_core = false;    // the out-of-core path renders sparseleap and none only
  bool show_stats = true;
};

enum class KeyAction { None, Changed, ResetView, Screenshot, Keyframe };

// 1-4: method none/bbox/octree/sparseleap (an unavailable one is ignored: None); M: cycle the mode;
// B: box overlay; D: depth-complexity view; R: reset the view; S: screenshot; K: camera keyframe.
// Settings changes return Changed.
KeyAction apply_key(ViewSettings& v, int key);

// Whether method m can render here (out of core: sparseleap and none).
bool method_available(const ViewSettings& v, SkipMethod m);

// dvr -> mip -> iso -> labels -> dvr, skipping labels without a label volume.
RenderMode next_mode(RenderMode m, bool has_labels);

// The four methods in the order of keys 1-4 and the panel's buttons.
inline constexpr SkipMethod kMethods[] = {SkipMethod::None, SkipMethod::BBox, SkipMethod::Octree,
                                          SkipMethod::SparseLeap};
inline constexpr RenderMode kModes[] = {RenderMode::Dvr, RenderMode::Mip, RenderMode::Iso, RenderMode::Labels};

// The LOD bias (DESIGN.md "Virtual memory") once RenderSettings has one; null before, and the panel
// hides it.
template <class R>
auto* lod_bias_of(R& r) {
  if constexpr (requires { r.lod_bias; }) {
    return &r.lod_bias;
  } else {
    return static_cast<std::conditional_t<std::is_const_v<R>, const float*, float*>>(nullptr);
  }
}

// Field by field (RenderSettings has padding): whether two settings render the same image.
bool same_settings(const RenderSettings& a, const RenderSettings& b);
bool same_camera(const Camera& a, const Camera& b);

}  // namespace sl::viewer
