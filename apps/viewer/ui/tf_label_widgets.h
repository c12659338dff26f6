// Custom ImGui widgets of the control panel: the transfer-function canvas and the label list.
// Each edits plain state (TfEditor, LabelState); PanelState carries selection across UI frames.
#pragma once

#include <vector>

#include "apps/viewer/ui/panels.h"

namespace sl::viewer {

// Control points over the histogram: left click adds or grabs, drag moves, right click deletes.
// Returns whether a point is being dragged (the viewer then renders coarse frames).
bool tf_canvas(TfEditor& tf, const std::vector<float>& hist, PanelState& st);
// Value and colour of the selected point, and deleting it.
void tf_point_editor(TfEditor& tf, PanelState& st);
// The file name with load and save buttons; errors go to st.status.
void tf_file_controls(TfEditor& tf, PanelState& st);
// Counts, mask switch, all / none / random fraction, search by id, the clipped list of labels.
void label_panel(LabelState& labels, PanelState& st);

}  // namespace sl::viewer
