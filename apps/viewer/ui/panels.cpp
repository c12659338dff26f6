#include "apps/viewer/ui/panels.h"

#include <imgui.h>
#include <imgui_stdlib.h>

#include <algorithm>

#include "apps/viewer/progressive.h"
#include "apps/viewer/ui/tf_label_widgets.h"

namespace sl::viewer {

namespace {

// Method and mode switches: the comparison the viewer exists for (seed 003), one click or key away.
void method_mode_controls(PanelModel& m) {
  RenderSettings& rs = m.view->render;
  ImGui::TextUnformatted("method (1-4)");
  for (std::size_t i = 0; i < std::size(kMethods); ++i) {
    if (i) ImGui::SameLine();
    ImGui::BeginDisabled(!method_available(*m.view, kMethods[i]));
    if (ImGui::RadioButton(to_string(kMethods[i]), rs.method == kMethods[i])) rs.method = kMethods[i];
    ImGui::EndDisabled();
  }
  ImGui::TextUnformatted("mode (M)");
  for (std::size_t i = 0; i < std::size(kModes); ++i) {
    if (i) ImGui::SameLine();
    const bool unavailable = kModes[i] == RenderMode::Labels && !m.view->has_labels;
    ImGui::BeginDisabled(unavailable);
    if (ImGui::RadioButton(to_string(kModes[i]), rs.mode == kModes[i])) rs.mode = kModes[i];
    ImGui::EndDisabled();
  }
  ImGui::Checkbox("b-box (B)", &rs.boxes_overlay);
  ImGui::SameLine();
  ImGui::Checkbox("depth complexity (D)", &rs.depth_complexity_view);
  if (m.stats) {
    // Segments per ray (SparseLeap, bbox) or octree nodes per ray (octree): the paper's Fig. 10.
    ImGui::Text("depth complexity  min %u  avg %.2f  max %u", m.stats->depth_complexity_min,
                m.stats->depth_complexity_avg, m.stats->depth_complexity_max);
  }
}

void sampling_controls(PanelModel& m) {
  RenderSettings& rs = m.view->render;
  ImGui::PushItemWidth(-110.0f);
  ImGui::SliderFloat("step", &rs.step, 0.1f, 4.0f, "%.2f voxel", ImGuiSliderFlags_Logarithmic);
  ImGui::SliderFloat("iso value", &rs.iso, m.tf->lo(), m.tf->hi(), "%.1f");
  if (auto* lod = lod_bias_of(rs)) {
    ImGui::SliderFloat("LOD bias", lod, 0.25f, 8.0f, "%.2f", ImGuiSliderFlags_Logarithmic);
  }
  ImGui::SliderFloat("resolution", &m.view->scale, 0.25f, 1.0f, "%.2f");
  ImGui::PopItemWidth();
  ImGui::Checkbox("early ray termination", &rs.ert);
  ImGui::SameLine();
  ImGui::Checkbox("stats", &m.view->show_stats);
}

void path_controls(PanelModel& m, PanelState& st, PanelActions& a) {
  PathRecorder& path = *m.path;
  ImGui::Text("%zu keyframes", path.size());
  ImGui::SameLine();
  if (ImGui::Button("add keyframe (K)")) a.keyframe = true;
  ImGui::SameLine();
  if (ImGui::Button("clear")) path.clear();
  bool timer_changed = ImGui::Checkbox("every", &st.keyframe_timer);
  ImGui::SameLine();
  ImGui::SetNextItemWidth(-1.0f);
  timer_changed |= ImGui::SliderFloat("##interval", &st.keyframe_interval, 0.2f, 10.0f, "%.1f s");
  if (timer_changed) path.set_interval(st.keyframe_timer ? double(st.keyframe_interval) : 0.0);
  int fps = path.frames_per_segment();
  ImGui::SetNextItemWidth(110.0f);
  if (ImGui::InputInt("frames / segment", &fps)) path.set_frames_per_segment(std::clamp(fps, 1, 10000));
  ImGui::SetNextItemWidth(-110.0f);
  ImGui::InputText("##path_file", &st.path_file);
  ImGui::SameLine();
  if (ImGui::Button("save path")) a.save_path = true;
}

// Two label/value pairs per line: half the height, so the overlay hides less of a small canvas.
void draw_stat_rows(const std::vector<StatRow>& rows) {
  if (!rows.empty() && ImGui::BeginTable("rows", 4, ImGuiTableFlags_SizingFixedFit)) {
    int column = 0;
    for (const StatRow& r : rows) {
      if (r.heading || column == 0) ImGui::TableNextRow();
      if (r.heading) {
        ImGui::TableSetColumnIndex(0);
        ImGui::TextDisabled("%s", r.label.c_str());
        column = 0;
        continue;
      }
      ImGui::TableSetColumnIndex(column);
      ImGui::TextUnformatted(r.label.c_str());
      ImGui::TableSetColumnIndex(column + 1);
      ImGui::TextUnformatted(r.value.c_str());
      column = column == 0 ? 2 : 0;
    }
    ImGui::EndTable();
  }
}

}  // namespace

PanelActions draw_control_panel(PanelModel& m, PanelState& st, float width, float height) {
  PanelActions a;
  ImGui::SetNextWindowPos(ImVec2(0.0f, 0.0f));
  ImGui::SetNextWindowSize(ImVec2(width, height));
  ImGui::Begin("sparseleap view", nullptr,
               ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoResize | ImGuiWindowFlags_NoCollapse |
                   ImGuiWindowFlags_NoBringToFrontOnFocus);
  method_mode_controls(m);
  sampling_controls(m);
  if (ImGui::Button("reset view (R)")) a.reset_view = true;
  ImGui::SameLine();
  if (ImGui::Button("screenshot (S)")) a.screenshot = true;

  if (ImGui::CollapsingHeader("transfer function", ImGuiTreeNodeFlags_DefaultOpen)) {
    a.dragging = tf_canvas(*m.tf, *m.histogram, st);
    tf_point_editor(*m.tf, st);
    tf_file_controls(*m.tf, st);
  }
  if (m.labels && ImGui::CollapsingHeader("labels", ImGuiTreeNodeFlags_DefaultOpen)) {
    label_panel(*m.labels, st);
  }
  if (ImGui::CollapsingHeader("camera path")) path_controls(m, st, a);
  if (!st.status.empty()) ImGui::TextWrapped("%s", st.status.c_str());
  ImGui::End();
  return a;
}

void draw_stats_overlay(const std::vector<StatRow>& rows, const OverlayInfo& info, float right, float top,
                        bool full) {
  if (!full && info.pending_loads == 0 && info.error.empty()) return;
  ImGui::SetNextWindowPos(ImVec2(right - 6.0f, top + 6.0f), ImGuiCond_Always, ImVec2(1.0f, 0.0f));
  ImGui::SetNextWindowBgAlpha(0.6f);
  const ImGuiWindowFlags flags = ImGuiWindowFlags_NoDecoration | ImGuiWindowFlags_AlwaysAutoResize |
                                 ImGuiWindowFlags_NoSavedSettings | ImGuiWindowFlags_NoFocusOnAppearing |
                                 ImGuiWindowFlags_NoNav | ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoInputs;
  ImGui::Begin("stats", nullptr, flags);
  // The progressive-loading indicator comes first: it says the image is still refining.
  if (info.pending_loads > 0) {
    ImGui::TextColored(ImVec4(1.0f, 0.8f, 0.2f, 1.0f), "loading %llu bricks", (unsigned long long)info.pending_loads);
  }
  if (full) {
    ImGui::Text("%dx%d%s%s  UI %.0f fps%s", info.render_width, info.render_height, info.level > 0 ? " coarse " : "",
                info.level > 0 ? level_label(info.level).c_str() : "", info.ui_fps, info.rendering ? "  *" : "");
  }
  if (!info.error.empty()) {
    ImGui::PushTextWrapPos(ImGui::GetCursorPosX() + 260.0f);
    ImGui::TextColored(ImVec4(1.0f, 0.35f, 0.3f, 1.0f), "%s", info.error.c_str());
    ImGui::PopTextWrapPos();
  }
  draw_stat_rows(rows);
  ImGui::End();
}

}  // namespace sl::viewer
