#include "apps/viewer/view_settings.h"

#include "apps/render_options.h"

namespace sl::viewer {

RenderMode next_mode(RenderMode m, bool has_labels) {
  switch (m) {
    case RenderMode::Dvr: return RenderMode::Mip;
    case RenderMode::Mip: return RenderMode::Iso;
    case RenderMode::Iso: return has_labels ? RenderMode::Labels : RenderMode::Dvr;
    case RenderMode::Labels: return RenderMode::Dvr;
  }
  return RenderMode::Dvr;
}

bool method_available(const ViewSettings& v, SkipMethod m) {
  return !v.out_of_core || app::out_of_core_method(m);
}

namespace {

// Keys 1-4: method m, unless it cannot render here.
KeyAction select_method(ViewSettings& v, SkipMethod m) {
  if (!method_available(v, m)) return KeyAction::None;
  // Out of core the B-splines run with --method none only.
  if (v.out_of_core && v.render.filter != Filter::Linear && m != SkipMethod::None) return KeyAction::None;
  v.render.method = m;
  return KeyAction::Changed;
}

// Key F: linear -> quadratic -> cubic -> linear.
KeyAction next_filter(ViewSettings& v) {
  // Out of core the B-splines need --method none (the bricks' apron bounds culling to trilinear).
  if (v.out_of_core && v.render.method != SkipMethod::None) return KeyAction::None;
  v.render.filter = v.render.filter == Filter::Linear      ? Filter::Quadratic
                    : v.render.filter == Filter::Quadratic ? Filter::Cubic
                                                           : Filter::Linear;
  return KeyAction::Changed;
}

}  // namespace

KeyAction apply_key(ViewSettings& v, int key) {
  if (key >= 'a' && key <= 'z') key -= 'a' - 'A';
  switch (key) {
    case '1':
    case '2':
    case '3':
    case '4': return select_method(v, kMethods[key - '1']);
    case 'M': v.render.mode = next_mode(v.render.mode, v.has_labels); return KeyAction::Changed;
    case 'B': v.render.boxes_overlay = !v.render.boxes_overlay; return KeyAction::Changed;
    case 'D': v.render.depth_complexity_view = !v.render.depth_complexity_view; return KeyAction::Changed;
    case 'L': v.render.lighting.enabled = !v.render.lighting.enabled; return KeyAction::Changed;
    case 'E':
      v.render.iso_method = v.render.iso_method == IsoMethod::Exact ? IsoMethod::Sampled : IsoMethod::Exact;
      return KeyAction::Changed;
    case 'F': return next_filter(v);
    case 'R': return KeyAction::ResetView;
    case 'S': return KeyAction::Screenshot;
    case 'K': return KeyAction::Keyframe;
    default: return KeyAction::None;
  }
}

namespace {

bool same_lod(const RenderSettings& a, const RenderSettings& b) {
  const float* la = lod_bias_of(a);
  const float* lb = lod_bias_of(b);
  return !la || *la == *lb;
}

}  // namespace

bool same_settings(const RenderSettings& a, const RenderSettings& b) {
  return a.width == b.width && a.height == b.height && a.mode == b.mode && a.method == b.method &&
         a.step == b.step && a.iso == b.iso && a.iso_method == b.iso_method && a.filter == b.filter && a.ert == b.ert && a.block == b.block &&
         a.gap_eps == b.gap_eps && a.lighting.enabled == b.lighting.enabled &&
         a.lighting.ambient == b.lighting.ambient && a.lighting.diffuse == b.lighting.diffuse &&
         a.lighting.specular == b.lighting.specular && a.lighting.shininess == b.lighting.shininess &&
         a.depth_complexity_view == b.depth_complexity_view && a.boxes_overlay == b.boxes_overlay &&
         same_lod(a, b);
}

bool same_camera(const Camera& a, const Camera& b) {
  return a.eye == b.eye && a.center == b.center && a.up == b.up && a.fov_deg == b.fov_deg && a.height == b.height &&
         a.projection == b.projection;
}

}  // namespace sl::viewer
