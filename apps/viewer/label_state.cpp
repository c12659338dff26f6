#include "apps/viewer/label_state.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace sl::viewer {

LabelState::LabelState(std::uint32_t label_count, const std::optional<LabelSet>& initial)
    : label_count_(label_count),
      enabled_(initial ? *initial : LabelSet::all(label_count)),
      masking_(initial.has_value()) {}

void LabelState::set_masking(bool on) {
  if (on == masking_) return;
  masking_ = on;
  ++revision_;
}

bool LabelState::toggle(std::uint32_t id) {
  if (!valid(id)) return false;
  return set_enabled(id, !enabled_.enabled(id));
}

bool LabelState::set_enabled(std::uint32_t id, bool on) {
  if (!valid(id)) return false;
  if (on) {
    enabled_.enable(id);
  } else {
    enabled_.disable(id);
  }
  touch();
  return true;
}

void LabelState::enable_all() {
  enabled_ = LabelSet::all(label_count_);
  touch();
}

void LabelState::enable_none() {
  enabled_ = parse_enable_spec("none", label_count_);
  touch();
}

void LabelState::random_fraction(double p, std::uint64_t seed) {
  p = std::isfinite(p) ? std::clamp(p, 0.0, 1.0) : 0.0;
  enabled_ = parse_enable_spec("fraction:" + std::to_string(p) + ":" + std::to_string(seed), label_count_);
  touch();
}

namespace {

// The voxel walk along one axis, for a ray entering voxel `voxel` at `entry` (voxel units) at t0:
// the step to the next voxel, the t where it is reached, and the t between two steps.
struct WalkAxis {
  int step = 0;
  float t_next = INFINITY;
  float t_delta = INFINITY;
};

WalkAxis walk_axis(float dir, float entry, int voxel, float t0) {
  if (dir > 0.0f) return {1, t0 + (float(voxel + 1) - entry) / dir, 1.0f / dir};
  if (dir < 0.0f) return {-1, t0 + (float(voxel) - entry) / dir, -1.0f / dir};
  return {};
}

// The axis whose next voxel boundary the ray meets first.
int nearest_axis(const vec3& t_next) {
  return t_next.x < t_next.y ? (t_next.x < t_next.z ? 0 : 2) : (t_next.y < t_next.z ? 1 : 2);
}

}  // namespace

std::uint32_t pick_label(const Volume& labels, const Camera& camera, int width, int height, int px, int py,
                         const LabelSet* accept) {
  if (labels.empty() || px < 0 || py < 0 || px >= width || py >= height) return 0;
  const RayGenerator gen = make_ray_generator(camera, width, height);
  const Ray ray = gen.ray(px, py);
  const VolumeDesc& d = labels.desc();
  const Interval hit = intersect(ray, Box3{vec3(0.0f), d.extent()});
  if (hit.empty() || hit.t1 <= 0.0f) return 0;
  const float t0 = std::max(hit.t0, 0.0f);

  // Work in voxel units: the first voxel is the one holding the entry point (nudged inside).
  const vec3 o = ray.origin / d.spacing;
  const vec3 dir = ray.dir / d.spacing;  // per unit of world t
  const vec3 entry = o + t0 * dir;
  ivec3 v = glm::clamp(ivec3(glm::floor(entry)), ivec3(0), d.dims - 1);
  ivec3 step;
  vec3 t_next, t_delta;
  for (int a = 0; a < 3; ++a) {
    const WalkAxis w = walk_axis(dir[a], entry[a], v[a], t0);
    step[a] = w.step;
    t_next[a] = w.t_next;
    t_delta[a] = w.t_delta;
  }
  const VolumeView view = labels.view();
  // At most one visit per voxel along each axis: bounds the loop even with rounding at the faces.
  const int max_steps = d.dims.x + d.dims.y + d.dims.z + 3;
  for (int i = 0; i < max_steps; ++i) {
    const std::uint32_t id = view.label(v.x, v.y, v.z);
    if (id != 0u && (!accept || accept->enabled(id))) return id;
    const int a = nearest_axis(t_next);
    if (t_next[a] > hit.t1) break;
    v[a] += step[a];
    if (v[a] < 0 || v[a] >= d.dims[a]) break;
    t_next[a] += t_delta[a];
  }
  return 0;
}

}  // namespace sl::viewer
