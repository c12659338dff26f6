// Loading what a frame needs (volume, labels, transfer function, camera) from the command line's
// options, shared by render, bench and view.
#pragma once

#include <optional>
#include <string>

#include "core/camera.h"
#include "core/labels.h"
#include "core/transfer_function.h"
#include "core/volume.h"

namespace sl::app {

struct SceneOptions {
  std::string volume;   // NRRD path; empty = built-in neurites
  std::string labels;   // optional NRRD label volume
  std::string tf;       // transfer-function JSON; empty = default for the data
  std::string camera;   // camera JSON; empty = default view
  std::string enable;   // enabled-label spec; empty = no label mask
};

struct LoadedScene {
  Volume volume;
  Volume labels;        // empty() if none
  std::uint32_t label_count = 0;
  TransferFunction tf;
  Camera camera;
  std::optional<LabelSet> enabled;
  std::string name;     // what was loaded, for messages
};

// Built-in data set: neurites, generated in memory (no file needed).
constexpr int kBuiltinSize = 256;

LoadedScene load_scene(const SceneOptions& o);

// Parses "WxH"; InputError("--size", ...) otherwise.
void parse_size(const std::string& s, int& w, int& h);

}  // namespace sl::app
