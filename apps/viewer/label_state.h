// Which segmentation labels are switched on (paper §5.2: culling by enabled segments), as plain
// state the label panel edits, and picking a label by casting a pixel's ray through the label volume.
#pragma once

#include <cstdint>
#include <optional>

#include "core/scene/camera.h"
#include "core/scene/labels.h"
#include "core/scene/volume.h"

namespace sl::viewer {

class LabelState {
 public:
  // `initial`: the --enable set, if any. Without one nothing is masked until the user edits the set
  // (then all labels start enabled, so the first edit changes exactly what it says).
  LabelState(std::uint32_t label_count, const std::optional<LabelSet>& initial);

  std::uint32_t label_count() const { return label_count_; }
  const LabelSet& enabled() const { return enabled_; }
  bool masking() const { return masking_; }
  // Turns the mask on or off without losing the set (dvr/mip/iso render all data when off).
  void set_masking(bool on);
  // The set the renderer should use: null when not masking.
  const LabelSet* mask() const { return masking_ ? &enabled_ : nullptr; }
  std::uint64_t revision() const { return revision_; }

  bool valid(std::uint32_t id) const { return id >= 1 && id <= label_count_; }
  bool is_enabled(std::uint32_t id) const { return enabled_.enabled(id); }
  // Flips one label; ignores 0 (background) and ids past label_count. Returns whether it changed.
  bool toggle(std::uint32_t id);
  bool set_enabled(std::uint32_t id, bool on);
  void enable_all();
  void enable_none();
  // Exactly round(p * label_count) labels, a deterministic subset per seed (the --enable
  // "fraction:P:SEED" rule, so a view can be reproduced from the command line).
  void random_fraction(double p, std::uint64_t seed);

 private:
  void touch() {
    masking_ = true;
    ++revision_;
  }

  std::uint32_t label_count_ = 0;
  LabelSet enabled_;
  bool masking_ = false;
  std::uint64_t revision_ = 0;
};

// The label under pixel (px, py) of a width x height image: walks the pixel's ray voxel by voxel
// (3D DDA, Amanatides & Woo) through the label volume and returns the first non-zero label that
// `accept` allows (null: any), or 0 when the ray meets none. The voxel walk matches what the caster
// shows: voxel i covers world [i, i + 1) * spacing.
std::uint32_t pick_label(const Volume& labels, const Camera& camera, int width, int height, int px, int py,
                         const LabelSet* accept = nullptr);

}  // namespace sl::viewer
