#include "apps/scene_renderer.h"

namespace sl::app {

SceneRenderer::SceneRenderer(const SourceScene& scene, const RenderOptions& o, const CheckedOptions& c,
                             Backend backend)
    : scene_(scene) {
  if (!scene.out_of_core()) {
    in_core_ = std::make_unique<FrameRenderer>(backend, c.lists);
    return;
  }
  out_of_core_ = std::make_unique<OutOfCoreRenderer>(scene.source, out_of_core_settings(o), c.settings.block,
                                                     make_cast_device(backend, c.cuda_sampler));
  if (c.lists == ListSource::Gl) out_of_core_->set_list_builder(make_gl_list_builder());
}

Frame SceneRenderer::render(const TransferFunction& tf, const LabelSet* enabled, const Camera& camera,
                            const RenderSettings& rs, const Camera* next) {
  if (out_of_core_) return out_of_core_->render(OutOfCoreScene{&tf, enabled, camera, next}, rs);
  Scene s;
  s.volume = scene_.volume.get();
  s.labels = scene_.labels.get();
  s.tf = &tf;
  s.enabled = enabled;
  s.camera = camera;
  return in_core_->render(s, rs);
}

void SceneRenderer::invalidate_lists() {
  if (in_core_) in_core_->invalidate_lists();
}

}  // namespace sl::app
