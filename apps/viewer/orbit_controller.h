// Mouse camera control as plain math (no window): orbit about the view centre, pan in the view
// plane, zoom along the view axis. Orbit keeps the distance to the centre, and the elevation is
// clamped short of the poles so the view never flips over the up axis.
#pragma once

#include "core/scene/camera.h"

namespace sl::viewer {

class OrbitController {
 public:
  static constexpr float kRadiansPerPixel = 0.008f;
  static constexpr float kMaxElevation = 1.5533430f;  // 89 degrees: the eye never reaches a pole
  static constexpr float kZoomPerStep = 0.9f;         // one wheel notch = 10 % closer

  // `home`'s up vector is the orbit axis (the world up of the data); R returns to `home`.
  explicit OrbitController(const Camera& home);

  void reset() { set_camera(home_); }
  // Drag by (dx, dy) pixels (y down, as the mouse reports): right = azimuth, down = elevation.
  void orbit(float dx, float dy);
  // Moves the centre and eye together so the point under the cursor follows it; the world size of
  // a pixel at the centre's depth comes from the field of view and the viewport height.
  void pan(float dx, float dy, int viewport_height);
  // Positive steps move closer (wheel up); the distance stays within a range around the home one.
  void zoom(float steps);
  // Adopts another camera (a loaded keyframe) while keeping the home's orbit axis.
  void set_camera(const Camera& c);

  Camera camera() const;
  const Camera& home() const { return home_; }
  float distance() const { return distance_; }
  float azimuth() const { return azimuth_; }
  float elevation() const { return elevation_; }

 private:
  vec3 direction() const;  // unit vector from the centre to the eye

  Camera home_;
  vec3 axis_{0.0f, 1.0f, 0.0f};  // orbit axis = up
  vec3 e1_{1.0f, 0.0f, 0.0f};    // azimuth 0, perpendicular to the axis
  vec3 e2_{0.0f, 0.0f, 1.0f};    // azimuth 90 degrees
  vec3 center_{0.0f};
  float distance_ = 1.0f;
  float azimuth_ = 0.0f;
  float elevation_ = 0.0f;
  float fov_deg_ = 30.0f;
  float height_ = 1.0f;  // orthographic view height, scaled with the zoom
  float home_distance_ = 1.0f;
  float home_height_ = 1.0f;
};

}  // namespace sl::viewer
