#include "apps/viewer/ui/viewer_scene.h"

#include "cache/out_of_core.h"
#include "core/error.h"

namespace sl::viewer {

ViewerScene load_viewer_scene(const ViewerOptions& o) { return app::load_source_scene(o.scene, o.cache_mb > 0); }

RenderWorker::RenderFn make_render_fn(const ViewerScene& s, const ViewerOptions& o, app::Backend backend) {
  if (!s.out_of_core()) {
    auto r = std::make_shared<app::FrameRenderer>(backend);
    return [r](const Scene& sc, const RenderSettings& rs) { return r->render(sc, rs); };
  }
  if (backend == app::Backend::Cuda) {
    throw InputError("--backend", "cuda: out-of-core rendering runs on the CPU backend so far");
  }
  if (!(o.lod_bias > 0.0f)) throw InputError("--lod-bias", "must be positive");
  OutOfCoreSettings os;
  os.brick = o.brick;
  os.cache_mb = o.cache_mb > 0 ? o.cache_mb : 1024;
  os.lod_bias = o.lod_bias;
  auto r = std::make_shared<OutOfCoreRenderer>(s.source, os, o.block);
  // The worker's Scene carries the snapshots (tf, labels, camera); the data come from the source.
  return [r](const Scene& sc, const RenderSettings& rs) {
    return r->render(OutOfCoreScene{sc.tf, sc.enabled, sc.camera}, rs);
  };
}

}  // namespace sl::viewer
