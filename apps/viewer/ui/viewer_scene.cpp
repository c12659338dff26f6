#include "apps/viewer/ui/viewer_scene.h"

#include "cache/out_of_core.h"
#include "core/error.h"

namespace sl::viewer {

ViewerScene load_viewer_scene(const ViewerOptions& o) {
  ViewerScene s;
  if (is_procedural_spec(o.scene.volume)) {
    // Same rules as `render` out of core: the source has its own (hashed) labels, no files.
    if (!o.scene.labels.empty()) throw InputError("--labels", "a procedural volume has its own labels");
    if (!o.scene.enable.empty()) {
      throw InputError("--enable", "label subsets of procedural volumes are not supported (their ids are hashed)");
    }
    s.source = parse_volume_spec(o.scene.volume);
    s.name = o.scene.volume;
    s.desc = s.source->desc();
    s.tf = o.scene.tf.empty() ? default_transfer_function(0.0f, 255.0f) : load_transfer_function(o.scene.tf);
    s.camera = o.scene.camera.empty() ? default_camera(s.desc.extent()) : load_camera(o.scene.camera);
    return s;
  }
  app::LoadedScene ls = app::load_scene(o.scene);
  s.name = ls.name;
  s.desc = ls.volume.desc();
  s.label_count = ls.label_count;
  s.tf = std::move(ls.tf);
  s.camera = ls.camera;
  s.enabled = std::move(ls.enabled);
  s.volume = std::make_shared<const Volume>(std::move(ls.volume));
  if (!ls.labels.empty()) s.labels = std::make_shared<const Volume>(std::move(ls.labels));
  if (o.cache_mb > 0) s.source = std::make_shared<MemoryVolumeSource>(s.volume, s.labels, s.name);
  return s;
}

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
