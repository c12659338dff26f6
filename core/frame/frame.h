// What every backend and front end shares about one frame: the render settings, the in-core scene, the
// frame (image + stats), their validation and the per-frame cast parameters.
#pragma once

#include "core/scene/camera.h"
#include "core/util/image.h"
#include "core/scene/labels.h"
#include "core/cast/raycast.h"
#include "core/scene/render_mode.h"
#include "core/frame/stats.h"
#include "core/scene/transfer_function.h"
#include "core/scene/volume.h"

namespace sl {

struct RenderSettings {
  int width = 1024;
  int height = 1024;
  RenderMode mode = RenderMode::Dvr;
  SkipMethod method = SkipMethod::SparseLeap;
  float step = 0.5f;       // sample distance in units of the smallest voxel spacing
  float iso = 128.0f;
  IsoMethod iso_method = IsoMethod::Exact;  // iso mode: exact per-cell roots or sampled bisection
  Filter filter = Filter::Linear;           // reconstruction: trilinear or a B-spline (--filter)
  bool ert = false;
  Lighting lighting;       // dvr, labels: Blinn–Phong with a headlight (--shade; VTK's parameters and defaults)
  int block = 16;          // culling block edge in voxels
  int fine_cell = -1;      // fine occupancy cell edge in voxels inside SparseLeap segments (0: off; -1: auto,
                           // kFineCellAuto in core/occupancy/fine_occupancy.h: 8 with the voxel mask, else 4)
  bool voxel_mask = true;  // inside occupied fine cells, a bit per trilinear cell (core/occupancy/fine_occupancy.h)
  bool tight_boxes = true; // with the voxel mask: SparseLeap lists from leaf boxes shrunk to its set cells,
                           // sparse subtrees flattened to their leaves first (flatten_sparse_subtrees,
                           // tighten_leaf_boxes; core/occupancy/occupancy_geometry.h)
  bool simd = true;        // CPU: DVR samples eight at a time with AVX2 where it runs (core/cast/sample_batch.h)
  bool leaps = true;       // out of core: leap over clear fine cells and clear unloaded stretches (RayCaster::
                           // march_leaping); the image and every count are the same (tests compare with off)
  float gap_eps = 0.0f;    // short-EMPTY-gap threshold in sample steps (0: off)
  bool depth_complexity_view = false;  // image shows segments (or octree nodes) per ray
  bool boxes_overlay = false;          // draw the occupancy geometry over the image

  bool operator==(const RenderSettings&) const = default;
};

struct Scene {
  const Volume* volume = nullptr;
  const Volume* labels = nullptr;       // optional, same dims
  const TransferFunction* tf = nullptr;
  const LabelSet* enabled = nullptr;    // dvr/mip/iso: mask by label when set; labels mode: null = all
  Camera camera;
};

struct Frame {
  Image image;  // RGBA + channels "samples" (and "depth_complexity")
  Stats stats;
};

// Validates the scene and settings; InputError names the offending option or file.
void validate(const Scene& scene, const RenderSettings& settings);
// The lighting parameters in VTK's ranges; InputError names the option.
void validate_lighting(const Lighting& lighting);

// The per-frame ray-casting parameters, built here for every renderer and backend. `step`: the sample
// distance in units of the smallest voxel spacing (the settings' step in core; out of core the step of
// the frame's finest level, DESIGN.md "Ray casting"); the transfer function's opacity is corrected for it.
// `enabled`: the label mask in dvr/mip/iso (applied when `label_volume`), the shown set in labels mode.
// `lod`: the level-of-detail rule (out of core; in core one level).
CastParams make_cast_params(const RenderSettings& settings, const VolumeDesc& volume, const TransferFunction& tf,
                            const LabelSet* enabled, bool label_volume, float step, const LodParams& lod = {});

// In core: the scene's parameters at the settings' step. `label_storage` holds the enabled set when
// labels mode has none given (then all labels are enabled); it must outlive the returned params.
CastParams make_cast_params(const Scene& scene, const RenderSettings& settings, LabelSet& label_storage);

}  // namespace sl
