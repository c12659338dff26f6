// The in-core frame pipeline (every backend): block metadata and culling over a volume held in memory,
// the occupancy structures of every skipping method, and the cast (the CPU tile loop unless a backend
// sets its own caster).
#pragma once

#include <functional>
#include <memory>
#include <span>

#include "core/frame.h"

namespace sl {

struct OccupancyGeometry;
struct SkipInputs;
struct SegmentListBuffer;
struct SegmentListStats;
struct VisibilityEntry;
struct RayGenerator;

class InCoreRenderer {
 public:
  // Events per pixel list. Longer lists are made conservative (their tail is sampled) and counted in
  // Stats::list_overflows; neurite scenes stay well below (about 30 events at most).
  static constexpr std::uint32_t kListCapacity = 32;

  InCoreRenderer();
  ~InCoreRenderer();
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
