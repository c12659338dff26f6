// The two editors with custom interaction: the transfer-function canvas (control points dragged over
// the data's histogram) and the label list (search, all/none/random, per-label toggles).
#include "apps/viewer/ui/tf_label_widgets.h"

#include <imgui.h>
#include <imgui_stdlib.h>

#include <algorithm>
#include <cmath>

namespace sl::viewer {

namespace {

ImU32 to_u32(const vec4& c) {
  return ImGui::ColorConvertFloat4ToU32(ImVec4(c.r, c.g, c.b, c.a));
}

// The transfer-function canvas on screen: value runs left to right over [lo, hi], opacity bottom to
// top; the colour ramp is a strip under it.
struct TfArea {
  ImVec2 p0, p1;  // the curve's rectangle (without the strip)
  float w = 0.0f, h = 0.0f;
  float lo = 0.0f, hi = 1.0f;
  static constexpr float kStrip = 10.0f;
  float to_x(float v) const { return p0.x + (v - lo) / (hi - lo) * w; }
  float to_y(float a) const { return p0.y + (1.0f - a) * h; }
};

// The histogram says where the data are, so points go where they matter.
void draw_histogram(ImDrawList* dl, const TfArea& r, const std::vector<float>& hist) {
  const int bins = int(hist.size());
  for (int i = 0; i < bins; ++i) {
    if (hist[std::size_t(i)] <= 0.0f) continue;
    const float x0 = r.p0.x + r.w * float(i) / float(bins);
    const float x1 = r.p0.x + r.w * float(i + 1) / float(bins);
    dl->AddRectFilled(ImVec2(x0, r.p1.y - hist[std::size_t(i)] * r.h), ImVec2(std::max(x1, x0 + 1.0f), r.p1.y),
                      IM_COL32(80, 84, 96, 255));
  }
}

void draw_colour_ramp(ImDrawList* dl, const TfArea& r, const TransferFunction& fn) {
  for (int x = 0; x < int(r.w); ++x) {
    vec4 c = fn.evaluate(r.lo + (float(x) + 0.5f) / r.w * (r.hi - r.lo));
    c.a = 1.0f;
    const float x0 = r.p0.x + float(x);
    dl->AddRectFilled(ImVec2(x0, r.p1.y + 1.0f), ImVec2(x0 + 1.0f, r.p1.y + TfArea::kStrip), to_u32(c));
  }
}

// The opacity curve through the control points, each drawn in its colour; the selected one ringed.
void draw_points(ImDrawList* dl, const TfArea& r, const std::vector<TfPoint>& pts, int selected) {
  for (std::size_t i = 1; i < pts.size(); ++i) {
    const ImVec2 a(r.to_x(pts[i - 1].value), r.to_y(pts[i - 1].rgba.a));
    dl->AddLine(a, ImVec2(r.to_x(pts[i].value), r.to_y(pts[i].rgba.a)), IM_COL32(230, 230, 230, 255), 1.5f);
  }
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const ImVec2 c(r.to_x(pts[i].value), r.to_y(pts[i].rgba.a));
    dl->AddCircleFilled(c, 5.0f, to_u32(vec4(vec3(pts[i].rgba), 1.0f)));
    const bool sel = int(i) == selected;
    dl->AddCircle(c, sel ? 7.0f : 5.0f, sel ? IM_COL32(255, 220, 0, 255) : IM_COL32(255, 255, 255, 255), 0, 1.5f);
  }
}

// The canvas's mouse at (mv, ma) in value and opacity: a left click grabs the point under it or makes
// one there, a left drag moves it, a right click deletes the point under it.
void edit_points(TfEditor& tf, PanelState& st, const TfArea& r, float mv, float ma) {
  const float px_per_value = r.w / (r.hi - r.lo);
  if (ImGui::IsItemClicked(ImGuiMouseButton_Left)) {
    // Grab a point under the cursor, or make one there (on the current colour).
    int i = tf.nearest(mv, ma, px_per_value, r.h, 7.0f);
    if (i < 0) i = tf.insert_at(mv, ma);
    st.tf_selected = st.tf_dragging = i;
  } else if (st.tf_dragging >= 0 && ImGui::IsItemActive() && ImGui::IsMouseDown(ImGuiMouseButton_Left)) {
    const ImVec2 d = ImGui::GetIO().MouseDelta;
    if (d.x != 0.0f || d.y != 0.0f) tf.move(st.tf_dragging, mv, ma);  // only real moves re-cull
  }
  if (!ImGui::IsMouseDown(ImGuiMouseButton_Left)) st.tf_dragging = -1;
  if (ImGui::IsItemClicked(ImGuiMouseButton_Right)) {
    const int i = tf.nearest(mv, ma, px_per_value, r.h, 7.0f);
    if (i >= 0 && tf.remove(i)) {
      if (st.tf_selected == i) st.tf_selected = -1;
      if (st.tf_selected > i) --st.tf_selected;
    }
  }
}

}  // namespace

bool tf_canvas(TfEditor& tf, const std::vector<float>& hist, PanelState& st) {
  TfArea r;
  r.w = std::max(ImGui::GetContentRegionAvail().x, 50.0f);
  r.h = 110.0f;
  r.p0 = ImGui::GetCursorScreenPos();
  r.p1 = ImVec2(r.p0.x + r.w, r.p0.y + r.h);
  ImGui::InvisibleButton("tf_canvas", ImVec2(r.w, r.h + TfArea::kStrip),
                         ImGuiButtonFlags_MouseButtonLeft | ImGuiButtonFlags_MouseButtonRight);
  const bool hovered = ImGui::IsItemHovered();
  r.lo = tf.lo();
  r.hi = tf.hi();
  const ImVec2 mouse = ImGui::GetIO().MousePos;
  const float mv = r.lo + std::clamp((mouse.x - r.p0.x) / r.w, 0.0f, 1.0f) * (r.hi - r.lo);
  const float ma = std::clamp(1.0f - (mouse.y - r.p0.y) / r.h, 0.0f, 1.0f);

  ImDrawList* dl = ImGui::GetWindowDrawList();
  dl->AddRectFilled(r.p0, ImVec2(r.p1.x, r.p1.y + TfArea::kStrip), IM_COL32(22, 22, 28, 255));
  draw_histogram(dl, r, hist);
  draw_colour_ramp(dl, r, tf.build());
  const auto& pts = tf.points();
  draw_points(dl, r, pts, st.tf_selected);
  edit_points(tf, st, r, mv, ma);
  if (hovered) ImGui::SetTooltip("value %.1f  opacity %.2f\nleft: add / drag   right: delete", mv, ma);
  if (st.tf_selected >= int(pts.size())) st.tf_selected = -1;
  return st.tf_dragging >= 0;
}

void tf_point_editor(TfEditor& tf, PanelState& st) {
  const int i = st.tf_selected;
  if (i < 0 || i >= int(tf.points().size())) {
    ImGui::TextDisabled("click a point to edit its colour");
    return;
  }
  TfPoint p = tf.points()[std::size_t(i)];
  float value = p.value;
  ImGui::SetNextItemWidth(120.0f);
  if (ImGui::DragFloat("value", &value, (tf.hi() - tf.lo()) / 500.0f, tf.lo(), tf.hi(), "%.2f")) {
    tf.move(i, value, p.rgba.a);
  }
  ImGui::SameLine();
  if (ImGui::Button("delete point")) {
    if (tf.remove(i)) st.tf_selected = -1;
  }
  float rgba[4] = {p.rgba.r, p.rgba.g, p.rgba.b, p.rgba.a};
  if (ImGui::ColorEdit4("colour", rgba, ImGuiColorEditFlags_AlphaBar)) {
    tf.set_color(i, vec4(rgba[0], rgba[1], rgba[2], rgba[3]));
  }
}

void tf_file_controls(TfEditor& tf, PanelState& st) {
  ImGui::SetNextItemWidth(-110.0f);
  ImGui::InputText("##tf_file", &st.tf_file);
  ImGui::SameLine();
  if (ImGui::Button("load")) {
    try {
      tf.load(st.tf_file);
      st.tf_selected = -1;
      st.status = "loaded " + st.tf_file;
    } catch (const std::exception& e) {
      st.status = e.what();  // a bad file must not end the session
    }
  }
  ImGui::SameLine();
  if (ImGui::Button("save")) {
    try {
      tf.save(st.tf_file);
      st.status = "saved " + st.tf_file;
    } catch (const std::exception& e) {
      st.status = e.what();
    }
  }
}

void label_panel(LabelState& labels, PanelState& st) {
  const std::uint32_t n = labels.label_count();
  ImGui::Text("%u labels, %u enabled", n, labels.enabled().count());
  bool mask = labels.masking();
  if (ImGui::Checkbox("mask dvr / mip / iso by labels", &mask)) labels.set_masking(mask);
  if (ImGui::Button("all")) labels.enable_all();
  ImGui::SameLine();
  if (ImGui::Button("none")) labels.enable_none();
  ImGui::SameLine();
  if (ImGui::Button("random")) labels.random_fraction(st.fraction, st.fraction_seed++);
  ImGui::SameLine();
  ImGui::SetNextItemWidth(-1.0f);
  ImGui::SliderFloat("##fraction", &st.fraction, 0.0f, 1.0f, "fraction %.2f");

  ImGui::SetNextItemWidth(110.0f);
  bool jump = ImGui::InputInt("find id", &st.search_id);
  st.search_id = std::clamp(st.search_id, 1, int(std::max<std::uint32_t>(n, 1)));
  const auto id = std::uint32_t(st.search_id);
  ImGui::SameLine();
  ImGui::ColorButton("##found", ImVec4(label_color(id).r, label_color(id).g, label_color(id).b, 1.0f),
                     ImGuiColorEditFlags_NoTooltip);
  ImGui::SameLine();
  if (ImGui::Button(labels.is_enabled(id) ? "on##found_toggle" : "off##found_toggle")) labels.toggle(id);
  ImGui::TextDisabled("click a label in the image to toggle it");

  // A clipped list: data sets have thousands of labels, only the visible rows are built.
  const float row = ImGui::GetFrameHeightWithSpacing();
  ImGui::BeginChild("label_list", ImVec2(0.0f, 6.0f * row), true);
  if (jump) ImGui::SetScrollY(float(id - 1) * row);
  ImGuiListClipper clipper;
  clipper.Begin(int(n), row);
  while (clipper.Step()) {
    for (int r = clipper.DisplayStart; r < clipper.DisplayEnd; ++r) {
      const auto lid = std::uint32_t(r + 1);
      const vec3 c = label_color(lid);
      ImGui::PushID(r);
      ImGui::ColorButton("##c", ImVec4(c.r, c.g, c.b, 1.0f), ImGuiColorEditFlags_NoTooltip);
      ImGui::SameLine();
      bool on = labels.is_enabled(lid);
      char name[32];
      std::snprintf(name, sizeof name, lid == id ? "label %u  <" : "label %u", lid);
      if (ImGui::Checkbox(name, &on)) labels.set_enabled(lid, on);
      ImGui::PopID();
    }
  }
  ImGui::EndChild();
}

}  // namespace sl::viewer
