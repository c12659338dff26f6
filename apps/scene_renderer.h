// The renderer of a loaded scene, built the same way for render, bench and view: in core the chosen
// backend's FrameRenderer, out of core an OutOfCoreRenderer over the scene's brick source with the
// backend's cast device; either with the chosen segment-list builder.
#pragma once

#include <memory>

#include "apps/backend.h"
#include "apps/render_options.h"
#include "apps/scene_loader.h"
#include "cache/out_of_core/renderer.h"

namespace sl::app {

class SceneRenderer {
 public:
  // `scene` must outlive the renderer. Throws InputError for settings the renderer refuses (a cache
  // too small for one brick per level, a block larger than the brick, a --lod beyond the levels, no
  // GL context for --lists gl). With --lists gl, construct it on the thread that renders.
  SceneRenderer(const SourceScene& scene, const RenderOptions& o, const CheckedOptions& c, Backend backend);

  // `next`: the view expected next, for out-of-core prefetch along the motion (optional).
  Frame render(const TransferFunction& tf, const LabelSet* enabled, const Camera& camera, const RenderSettings& rs,
               const Camera* next = nullptr);

  // In core: the next frame rebuilds its segment lists (bench's rasterization frames).
  void invalidate_lists();
  // Null in core.
  const OutOfCoreRenderer* out_of_core() const { return out_of_core_.get(); }
  OutOfCoreRenderer* out_of_core() { return out_of_core_.get(); }

 private:
  const SourceScene& scene_;
  std::unique_ptr<FrameRenderer> in_core_;
  std::unique_ptr<OutOfCoreRenderer> out_of_core_;
};

}  // namespace sl::app
