#include "core/frame/frame.h"

#include "core/util/error.h"
#include "core/occupancy/fine_occupancy.h"

namespace sl {

void validate_lighting(const Lighting& l) {
  // VTK's ranges (vtkVolumeProperty): coefficients in [0, 1], specular power in [0, 128].
  const auto in = [](float v, float lo, float hi) { return v >= lo && v <= hi; };  // false for NaN
  if (!in(l.ambient, 0.0f, 1.0f)) throw InputError("--ambient", "must be in [0, 1]");
  if (!in(l.diffuse, 0.0f, 1.0f)) throw InputError("--diffuse", "must be in [0, 1]");
  if (!in(l.specular, 0.0f, 1.0f)) throw InputError("--specular", "must be in [0, 1]");
  if (!in(l.shininess, 0.0f, 128.0f)) throw InputError("--shininess", "must be in [0, 128]");
}

void validate(const Scene& scene, const RenderSettings& s) {
  if (!scene.volume || scene.volume->empty()) throw InputError("render", "no volume");
  if (!scene.tf) throw InputError("render", "no transfer function");
  if (s.width <= 0 || s.height <= 0 || s.width > 16384 || s.height > 16384) {
    throw InputError("--size", "image size must be between 1x1 and 16384x16384");
  }
  if (!(s.step > 0.0f) || s.step > 64.0f) throw InputError("--step", "step must be in (0, 64]");
  validate_fine_cell(s.fine_cell);
  validate_lighting(s.lighting);
  if (scene.labels && scene.labels->dims() != scene.volume->dims()) {
    throw InputError("--labels", "label volume dims differ from the intensity volume's");
  }
  if (s.mode == RenderMode::Labels && !scene.labels) {
    throw InputError("--mode", "labels mode needs a label volume (--labels)");
  }
}

CastParams make_cast_params(const RenderSettings& s, const VolumeDesc& d, const TransferFunction& tf,
                            const LabelSet* enabled, bool label_volume, float step, const LodParams& lod) {
  CastParams p;
  p.mode = s.mode;
  p.dt = step * d.min_spacing();
  p.inv_dt = 1.0f / p.dt;
  p.iso = s.iso;
  p.iso_method = s.iso_method;
  p.filter = s.filter;
  p.ert = s.ert;
  p.lighting = s.lighting;
  p.lighting.enabled = s.lighting.enabled && (s.mode == RenderMode::Dvr || s.mode == RenderMode::Labels);
  // The guard: 1e-3 of the transfer function's value range per voxel of the finest level (labels:
  // 1e-3 of the mask's range 1, per voxel).
  const float range = s.mode == RenderMode::Labels ? 1.0f : tf.vmax() - tf.vmin();
  p.lighting.min_gradient = 1e-3f * range / d.min_spacing();
  p.spacing = d.spacing;
  p.tf = tf.view(step);  // α' = 1 − (1 − α)^(dt / min spacing), and dt / min spacing = step
  p.label_mask = enabled != nullptr && label_volume && s.mode != RenderMode::Labels;
  p.simd = s.simd;
  p.leaps = s.leaps;
  if (enabled) p.labels = enabled->view();
  p.lod = lod;
  return p;
}

CastParams make_cast_params(const Scene& scene, const RenderSettings& s, LabelSet& label_storage) {
  const LabelSet* enabled = scene.enabled;
  if (s.mode == RenderMode::Labels && !enabled) {
    label_storage = parse_enable_spec("all", max_label(*scene.labels));
    enabled = &label_storage;
  }
  return make_cast_params(s, scene.volume->desc(), *scene.tf, enabled, scene.labels != nullptr, s.step);
}

}  // namespace sl
