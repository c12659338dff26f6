#include "core/cpu_renderer.h"

#include <algorithm>
#include <atomic>
#include <cmath>

#include "core/error.h"
#include "core/parallel.h"
#include "core/raycast.h"

namespace sl {

struct CpuRenderer::State {};

CpuRenderer::CpuRenderer() : state_(std::make_unique<State>()) {}
CpuRenderer::~CpuRenderer() = default;

void validate(const Scene& scene, const RenderSettings& s) {
  if (!scene.volume || scene.volume->empty()) throw InputError("render", "no volume");
  if (!scene.tf) throw InputError("render", "no transfer function");
  if (s.width <= 0 || s.height <= 0 || s.width > 16384 || s.height > 16384) {
    throw InputError("--size", "image size must be between 1x1 and 16384x16384");
  }
  if (!(s.step > 0.0f) || s.step > 64.0f) throw InputError("--step", "step must be in (0, 64]");
  if (scene.labels && scene.labels->dims() != scene.volume->dims()) {
    throw InputError("--labels", "label volume dims differ from the intensity volume's");
  }
  if (s.mode == RenderMode::Labels && !scene.labels) {
    throw InputError("--mode", "labels mode needs a label volume (--labels)");
  }
}

CastParams make_cast_params(const Scene& scene, const RenderSettings& s, LabelSet& label_storage) {
  const VolumeDesc& d = scene.volume->desc();
  CastParams p;
  p.mode = s.mode;
  p.dt = s.step * d.min_spacing();
  p.inv_dt = 1.0f / p.dt;
  p.iso = s.iso;
  p.ert = s.ert;
  p.spacing = d.spacing;
  p.tf = scene.tf->view(s.step);  // α' = 1 − (1 − α)^(dt / min spacing), and dt / min spacing = step
  const LabelSet* enabled = scene.enabled;
  if (s.mode == RenderMode::Labels && !enabled) {
    label_storage = parse_enable_spec("all", max_label(*scene.labels));
    enabled = &label_storage;
  }
  p.label_mask = enabled != nullptr && scene.labels != nullptr && s.mode != RenderMode::Labels;
  if (enabled) p.labels = enabled->view();
  return p;
}

namespace {

template <class T>
DenseGrid<T> grid_of(const Volume* v) {
  DenseGrid<T> g;
  if (v && !v->empty()) {
    g.data = v->as<T>();
    g.dims = v->dims();
    g.inv_spacing = 1.0f / v->desc().spacing;
  }
  return g;
}

struct Counters {
  std::atomic<std::uint64_t> samples{0}, useful{0}, rays{0};
};

// Per-pixel integration for the method at hand; `spans(x, y, ray, t_entry, t_exit, k_end, caster, acc)`
// calls caster.march on the index ranges it does not skip.
template <class VT, class LT, class Spans>
void cast_image(const RayCaster<VT, LT>& caster, const RayGenerator& gen, const Box3& vbox, Image& img,
                Counters& counters, Spans&& spans) {
  auto& samples_ch = img.channel("samples");
  float* depth_ch = nullptr;  // iso: hit distance t per pixel, -1 where the ray finds no surface
  if (caster.p.mode == RenderMode::Iso) {
    auto& d = img.channel("depth");
    std::fill(d.begin(), d.end(), -1.0f);
    depth_ch = d.data();
  }
  parallel_for_tiles(img.width, img.height, [&](int x0, int y0, int x1, int y1) {
    std::uint64_t samples = 0, useful = 0, rays = 0;
    for (int y = y0; y < y1; ++y) {
      for (int x = x0; x < x1; ++x) {
        const Ray ray = gen.ray(x, y);
        const Interval iv = intersect(ray, vbox);
        const float t_entry = iv.t0 > 0.0f ? iv.t0 : 0.0f;
        if (!(iv.t1 > t_entry)) continue;
        const int k_end = sample_index(iv.t1, t_entry, caster.p.inv_dt);
        RayAccum acc;
        spans(x, y, ray, t_entry, iv.t1, k_end, acc);
        const std::size_t i = std::size_t(y) * img.width + x;
        img.rgba[i] = caster.resolve(acc);
        samples_ch[i] = float(acc.samples);
        if (depth_ch) depth_ch[i] = acc.hit_t;
        samples += acc.samples;
        useful += acc.useful_samples;
        ++rays;
      }
    }
    counters.samples += samples;
    counters.useful += useful;
    counters.rays += rays;
  });
}

template <class VT, class LT>
void render_typed(const Scene& scene, const RenderSettings& s, const CastParams& params, Frame& frame) {
  RayCaster<VT, LT> caster{params, grid_of<VT>(scene.volume), grid_of<LT>(scene.labels)};
  const RayGenerator gen = make_ray_generator(scene.camera, s.width, s.height);
  const Box3 vbox{vec3(0.0f), scene.volume->desc().extent()};
  Counters counters;
  Timer t;
  switch (s.method) {
    case SkipMethod::None:
    default:
      cast_image(caster, gen, vbox, frame.image, counters,
                 [&](int, int, const Ray& ray, float t_entry, float, int k_end, RayAccum& acc) {
                   caster.march(ray, t_entry, 0, k_end, acc);
                 });
      break;
  }
  frame.stats.time_ms.raycast = t.ms();
  frame.stats.samples = counters.samples;
  frame.stats.useful_samples = counters.useful;
  frame.stats.rays = counters.rays;
}

template <class VT>
void render_labels_typed(const Scene& scene, const RenderSettings& s, const CastParams& p, Frame& f) {
  if (!scene.labels) return render_typed<VT, std::uint8_t>(scene, s, p, f);
  switch (scene.labels->type()) {
    case VoxelType::U8: return render_typed<VT, std::uint8_t>(scene, s, p, f);
    case VoxelType::U16: return render_typed<VT, std::uint16_t>(scene, s, p, f);
    case VoxelType::U32: return render_typed<VT, std::uint32_t>(scene, s, p, f);
    case VoxelType::F32: throw InputError("--labels", "label volume must be of an integer type");
  }
}

}  // namespace

Frame CpuRenderer::render(const Scene& scene, const RenderSettings& s) {
  validate(scene, s);
  Timer total;
  Frame frame;
  frame.image = Image(s.width, s.height);
  frame.stats.width = s.width;
  frame.stats.height = s.height;
  frame.stats.method = to_string(s.method);
  frame.stats.mode = to_string(s.mode);

  LabelSet label_storage;
  const CastParams p = make_cast_params(scene, s, label_storage);
  switch (scene.volume->type()) {
    case VoxelType::U8: render_labels_typed<std::uint8_t>(scene, s, p, frame); break;
    case VoxelType::U16: render_labels_typed<std::uint16_t>(scene, s, p, frame); break;
    case VoxelType::U32: render_labels_typed<std::uint32_t>(scene, s, p, frame); break;
    case VoxelType::F32: render_labels_typed<float>(scene, s, p, frame); break;
  }
  frame.stats.time_ms.total = total.ms();
  return frame;
}

}  // namespace sl
