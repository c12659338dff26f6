// The CPU backend: the reference renderer for every method and mode, parallel over screen tiles.
#pragma once

#include <functional>
#include <memory>
#include <span>

#include "core/camera.h"
#include "core/image.h"
#include "core/labels.h"
#include "core/raycast.h"
#include "core/render_mode.h"
#include "core/stats.h"
#include "core/transfer_function.h"
#include "core/volume.h"

namespace sl {

struct RenderSettings {
  int width = 1024;
  int height = 1024;
  RenderMode mode = RenderMode::Dvr;
  SkipMethod method = SkipMethod::SparseLeap;
  float step = 0.5f;       // sample distance in units of the smallest voxel spacing
  float iso = 128.0f;
  bool ert = false;
  int block = 16;          // culling block edge in voxels
  float gap_eps = 0.0f;    // short-EMPTY-gap threshold in sample steps (0: off)
  bool depth_complexity_view = false;  // image shows segments (or octree nodes) per ray
  bool boxes_overlay = false;          // draw the occupancy geometry over the image
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

// The per-frame ray-casting parameters every backend uses. `label_storage` holds the enabled set when
// labels mode has none given (then all labels are enabled); it must outlive the returned params.
CastParams make_cast_params(const Scene& scene, const RenderSettings& settings, LabelSet& label_storage);

struct OccupancyGeometry;
struct SkipInputs;
struct SegmentListBuffer;
struct SegmentListStats;
struct VisibilityEntry;
struct RayGenerator;

class CpuRenderer {
 public:
  // Events per pixel list. Longer lists are made conservative (their tail is sampled) and counted in
  // Stats::list_overflows; neurite scenes stay well below (about 30 events at most).
  static constexpr std::uint32_t kListCapacity = 32;

  CpuRenderer();
  ~CpuRenderer();
  // Renders a frame. Metadata, occupancy structures and segment lists persist between calls and are
  // rebuilt only when their inputs change (a new volume or block size; new block classes after a
  // transfer-function or label change; a new view).
  Frame render(const Scene& scene, const RenderSettings& settings);
  // Forces the next frame to rebuild its segment lists even if the view is unchanged (benchmarks
  // measure rasterization frames honestly this way).
  void invalidate_lists();
  // The occupancy geometry of the last frame (null before a skipping method has run).
  const OccupancyGeometry* geometry() const;

  // Hooks for the other backends; empty (the default) means the CPU's own.
  // Builds SparseLeap segment lists with build_segment_lists's signature into `out` (keeping its
  // size and capacity), e.g. GlSegmentListBuilder for `--lists gl`; lists equal to the CPU builder's
  // give the same image (DESIGN.md §7, tests/gl/gl_lists_renderer_test.cpp).
  using ListBuilder = std::function<SegmentListStats(const OccupancyGeometry&, std::span<const VisibilityEntry>,
                                                     const RayGenerator&, SegmentListBuffer& out, float eps)>;
  void set_list_builder(ListBuilder builder);
  // Casts the frame (fills frame.image and the ray-casting stats, as cast_frame does) from the
  // skipping structures this renderer prepared, e.g. the CUDA kernels.
  using Caster = std::function<void(const Scene&, const RenderSettings&, const CastParams&, const SkipInputs&,
                                    Frame&)>;
  void set_caster(Caster caster);

 private:
  struct State;
  SkipInputs prepare_skipping(const Scene& scene, const RenderSettings& s, const CastParams& p, Stats& st);

  std::unique_ptr<State> state_;
  const LabelSet* active_labels_ = nullptr;  // enabled set of the frame being rendered
  ListBuilder list_builder_;
  Caster caster_;
};

}  // namespace sl
