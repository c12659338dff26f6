#include "cache/out_of_core/cache_pressure.h"

#include <algorithm>
#include <cmath>

namespace sl {

namespace {

// What a frame looks at and how it samples (FNV-1a over the camera and sampling, seeded with the
// culling key).
std::uint64_t view_key(const Camera& c, const RenderSettings& s, std::uint64_t cull) {
  std::uint64_t h = 1469598103934665603ull ^ cull;
  auto mix = [&h](const void* p, std::size_t n) {
    const auto* b = static_cast<const unsigned char*>(p);
    for (std::size_t i = 0; i < n; ++i) h = (h ^ b[i]) * 1099511628211ull;
  };
  const float f[] = {c.eye.x, c.eye.y, c.eye.z, c.center.x, c.center.y, c.center.z, c.up.x, c.up.y, c.up.z,
                     c.fov_deg, c.height, s.step};
  const int i[] = {int(c.projection), s.width, s.height};
  mix(f, sizeof f);
  mix(i, sizeof i);
  return h;
}

}  // namespace

CachePressure::CachePressure(int levels, const OutOfCoreSettings& settings)
    : levels_(levels), pinned_(settings.lod), lod_bias_(settings.lod_bias) {}

void CachePressure::begin_frame(const Camera& camera, const RenderSettings& s, std::uint64_t cull_key) {
  const std::uint64_t vk = view_key(camera, s, cull_key);
  if (vk == view_key_) return;
  view_key_ = vk;
  largest_overflow_step_ = -1;  // a new view may fit where the last did not
  unfit_working_set_ = 0;
}

void CachePressure::adapt(std::size_t wanted, std::size_t slots, bool settled,
                          const std::function<bool()>& loads_done) {
  const int before = pressure_;
  if (wanted > slots && pressure_ == 0) unfit_working_set_ = std::max(unfit_working_set_, wanted);
  if (pinned_ < 0) {  // a pinned level is never coarsened (the frame reports the shortfall)
    const int most = 4 * (levels_ - 1);
    if (wanted > slots) {
      largest_overflow_step_ = std::max(largest_overflow_step_, pressure_);
      // Bricks on screen scale about with the square of the footprint: a quarter octave per factor
      // 2^(1/2) of excess, at least one step.
      const double excess = std::log2(double(wanted) / double(slots));
      pressure_ = std::min(most, pressure_ + std::max(1, int(std::ceil(2.0 * excess))));
    } else if (pressure_ > 0 && pressure_ - 1 > largest_overflow_step_ && settled && loads_done()) {
      --pressure_;  // settled with room to spare for a try: refine one step
    }
  }
  changed_ = pressure_ != before;
}

FrameLod CachePressure::frame_lod(const RayGenerator& gen, const RenderSettings& s, const VolumeDesc& d) const {
  FrameLod f;
  f.lod.levels = levels_;
  f.lod.pinned = pinned_;
  const float pixel = 2.0f * gen.half_h / float(s.height);
  if (gen.orthographic) {
    f.lod.pixel_size = pixel;
  } else {
    f.lod.pixel_angle = pixel;
  }
  f.lod.inv_voxel = lod_bias_ / d.min_spacing();
  f.footprint = f.lod;
  if (pressure_ > 0) f.lod.inv_voxel *= std::exp2(float(pressure_) * 0.25f);
  const vec3 nearest = glm::clamp(gen.eye, vec3(0.0f), d.extent());
  f.nearest_t = gen.orthographic ? 0.0f : glm::length(nearest - gen.eye);
  const int finest = f.lod.level_at(f.nearest_t);
  f.step = s.step * float(1 << finest);
  f.lod.grid_level = finest;
  return f;
}

}  // namespace sl
