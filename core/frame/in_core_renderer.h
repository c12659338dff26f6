// The in-core renderer (every backend): block metadata and culling over a volume held in memory, the
// occupancy tree built from the block classes, the frame pipeline over it (core/frame/pipeline.h), the
// octree baseline on top, and the cast (the CPU tile loop unless a backend sets its own caster).
#pragma once

#include <functional>
#include <memory>

#include "core/frame/frame.h"
#include "core/frame/pipeline.h"

namespace sl {

struct CullParams;
struct FineOccupancyView;
struct SkipInputs;
class BrickedVolume;

class InCoreRenderer {
 public:
  InCoreRenderer();
  ~InCoreRenderer();
  // Renders a frame. Metadata, occupancy structures and segment lists persist between calls and are
  // rebuilt only when their inputs change (a new volume or block size; new block classes after a
  // transfer-function or label change; a new view).
  Frame render(const Scene& scene, const RenderSettings& settings);
  // Forces the next frame to rebuild its segment lists even if the view is unchanged (benchmarks
  // measure rasterization frames honestly this way).
  void invalidate_lists() { pipeline_.invalidate_lists(); }

  // Hooks for the other backends; empty (the default) means the CPU's own.
  // Builds the SparseLeap segment lists, e.g. with the GL rasterizer (`--lists gl`).
  void set_list_builder(ListBuilder builder) { pipeline_.set_list_builder(std::move(builder)); }
  // Casts the frame (fills frame.image and the ray-casting stats, as cast_frame does) from the
  // skipping structures this renderer prepared, e.g. the CUDA kernels.
  using Caster = std::function<void(const Scene&, const RenderSettings&, const CastParams&, const SkipInputs&,
                                    Frame&)>;
  void set_caster(Caster caster) { caster_ = std::move(caster); }

 private:
  struct State;
  SkipInputs prepare_skipping(const Scene& scene, const RenderSettings& s, const CastParams& p,
                              const LabelSet* labels, const RayGenerator& gen, Stats& st);
  // The fine occupancy grid for SparseLeap (core/occupancy/fine_occupancy.h), built or re-derived as needed.
  FineOccupancyView fine_occupancy(const Scene& scene, const RenderSettings& s, const CullParams& cull, Stats& st);
  // The volume copied into bricks for the CPU batch, made once per volume where the batch can run
  // (u8/u16, DVR unlit, trilinear, --simd on, AVX2), else null; the time counts as metadata.
  const BrickedVolume* bricked_volume(const Scene& scene, const CastParams& p, Stats& st);

  std::unique_ptr<State> state_;
  FramePipeline pipeline_;
  Caster caster_;
};

}  // namespace sl
