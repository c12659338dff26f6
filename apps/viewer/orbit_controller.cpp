#include "apps/viewer/orbit_controller.h"

#include <algorithm>
#include <cmath>

namespace sl::viewer {

namespace {

constexpr float kPi = 3.14159265358979f;
// Zoom range relative to the home distance: close enough to fly inside the volume (DESIGN.md "Ray
// segment lists" supports cameras inside it), far enough to see it as a speck; never zero, so the
// view stays defined.
constexpr float kMinZoom = 0.02f;
constexpr float kMaxZoom = 20.0f;

}  // namespace

OrbitController::OrbitController(const Camera& home) : home_(home) {
  const float up_len = glm::length(home.up);
  axis_ = up_len > 0.0f ? home.up / up_len : vec3(0.0f, 1.0f, 0.0f);
  // Azimuth 0 is the home eye's direction projected onto the plane normal to the axis; when the
  // home looks straight along the axis, any perpendicular will do.
  vec3 off = home.eye - home.center;
  vec3 flat = off - glm::dot(off, axis_) * axis_;
  if (glm::length(flat) < 1e-6f * std::max(glm::length(off), 1e-30f)) {
    flat = std::abs(axis_.x) < 0.9f ? glm::cross(axis_, vec3(1, 0, 0)) : glm::cross(axis_, vec3(0, 1, 0));
  }
  e1_ = glm::normalize(flat);
  e2_ = glm::cross(e1_, axis_);
  set_camera(home);
  home_distance_ = distance_;
  home_height_ = height_;
}

void OrbitController::set_camera(const Camera& c) {
  center_ = c.center;
  fov_deg_ = c.fov_deg;
  height_ = c.height;
  const vec3 off = c.eye - c.center;
  distance_ = std::max(glm::length(off), 1e-6f);
  const vec3 n = off / distance_;
  elevation_ = std::clamp(std::asin(std::clamp(glm::dot(n, axis_), -1.0f, 1.0f)), -kMaxElevation, kMaxElevation);
  azimuth_ = std::atan2(glm::dot(n, e2_), glm::dot(n, e1_));
}

vec3 OrbitController::direction() const {
  const float ce = std::cos(elevation_);
  return ce * (std::cos(azimuth_) * e1_ + std::sin(azimuth_) * e2_) + std::sin(elevation_) * axis_;
}

void OrbitController::orbit(float dx, float dy) {
  if (!std::isfinite(dx) || !std::isfinite(dy)) return;
  // Dragging right turns the object right, i.e. moves the eye left around it (e2_ points to the
  // home view's left); dragging down shows more of the top, as a trackball does.
  azimuth_ = std::remainder(azimuth_ + dx * kRadiansPerPixel, 2.0f * kPi);
  elevation_ = std::clamp(elevation_ + dy * kRadiansPerPixel, -kMaxElevation, kMaxElevation);
}

void OrbitController::pan(float dx, float dy, int viewport_height) {
  if (viewport_height <= 0 || !std::isfinite(dx) || !std::isfinite(dy)) return;
  const Camera c = camera();
  const float world_per_px =
      c.projection == Projection::Orthographic
          ? c.height / float(viewport_height)
          : 2.0f * distance_ * std::tan(0.5f * fov_deg_ * kPi / 180.0f) / float(viewport_height);
  const vec3 fwd = -direction();
  const vec3 right = glm::normalize(glm::cross(fwd, axis_));
  const vec3 up = glm::cross(right, fwd);
  // The scene follows the cursor: the centre moves against the drag.
  center_ += (-dx * right + dy * up) * world_per_px;
}

void OrbitController::zoom(float steps) {
  if (!std::isfinite(steps)) return;
  const float f = std::pow(kZoomPerStep, steps);
  distance_ = std::clamp(distance_ * f, kMinZoom * home_distance_, kMaxZoom * home_distance_);
  // Orthographic views do not get bigger as the eye approaches; their height is the zoom.
  height_ = std::clamp(height_ * f, kMinZoom * home_height_, kMaxZoom * home_height_);
}

Camera OrbitController::camera() const {
  Camera c = home_;
  c.center = center_;
  c.eye = center_ + distance_ * direction();
  c.up = axis_;
  c.fov_deg = fov_deg_;
  c.height = height_;
  return c;
}

}  // namespace sl::viewer
