#include "apps/viewer/orbit_controller.h"

#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include <cmath>

namespace sl::viewer {
namespace {

Camera home() { return default_camera(vec3(256.0f, 200.0f, 128.0f)); }

float dist(const Camera& c) { return glm::length(c.eye - c.center); }

TEST(OrbitController, StartsAtTheHomeCamera) {
  const OrbitController o(home());
  const Camera c = o.camera();
  EXPECT_NEAR(glm::length(c.eye - home().eye), 0.0f, 1e-3f);
  EXPECT_EQ(c.center, home().center);
  EXPECT_FLOAT_EQ(c.fov_deg, home().fov_deg);
}

TEST(OrbitController, OrbitKeepsTheDistanceAndCentre) {
  OrbitController o(home());
  const float d0 = dist(o.camera());
  o.orbit(120.0f, -45.0f);
  o.orbit(-300.0f, 80.0f);
  EXPECT_NEAR(dist(o.camera()), d0, 1e-3f * d0);
  EXPECT_EQ(o.camera().center, home().center);
  EXPECT_GT(glm::length(o.camera().eye - home().eye), 1.0f);  // it did move
}

TEST(OrbitController, DraggingRightMovesTheEyeToTheLeft) {
  OrbitController o(home());
  const RayGenerator g0 = make_ray_generator(o.camera(), 100, 100);
  const vec3 eye0 = o.camera().eye;
  o.orbit(10.0f, 0.0f);
  // The eye moved against the old camera's right vector: the object turned right.
  EXPECT_LT(glm::dot(o.camera().eye - eye0, g0.right), 0.0f);
}

TEST(OrbitController, ElevationIsClampedSoTheViewNeverFlips) {
  OrbitController o(home());
  for (int i = 0; i < 200; ++i) o.orbit(3.0f, 50.0f);  // far past the pole
  EXPECT_LE(o.elevation(), OrbitController::kMaxElevation + 1e-6f);
  const Camera c = o.camera();
  const RayGenerator g = make_ray_generator(c, 64, 64);  // throws if up is parallel to the view
  EXPECT_GT(glm::dot(g.up, home().up), 0.0f);           // screen up still points to world up
  for (int i = 0; i < 400; ++i) o.orbit(-1.0f, -50.0f);
  EXPECT_GE(o.elevation(), -OrbitController::kMaxElevation - 1e-6f);
  EXPECT_GT(glm::dot(make_ray_generator(o.camera(), 64, 64).up, home().up), 0.0f);
}

RC_GTEST_PROP(OrbitControllerProperty, AnyDragsKeepDistanceAndAnUprightView, ()) {
  OrbitController o(home());
  const float d0 = o.distance();
  const int n = *rc::gen::inRange(1, 40);
  for (int i = 0; i < n; ++i) {
    o.orbit(float(*rc::gen::inRange(-2000, 2000)), float(*rc::gen::inRange(-2000, 2000)));
    const Camera c = o.camera();
    RC_ASSERT(std::abs(dist(c) - d0) <= 1e-3f * d0);
    const RayGenerator g = make_ray_generator(c, 32, 32);
    RC_ASSERT(glm::dot(g.up, home().up) > 0.0f);
  }
}

TEST(OrbitController, ZoomScalesTheDistanceWithinLimits) {
  OrbitController o(home());
  const float d0 = o.distance();
  o.zoom(1.0f);
  EXPECT_NEAR(o.distance(), d0 * OrbitController::kZoomPerStep, 1e-3f * d0);
  o.zoom(-2.0f);
  EXPECT_NEAR(o.distance(), d0 / OrbitController::kZoomPerStep, 1e-3f * d0);
  for (int i = 0; i < 500; ++i) o.zoom(5.0f);
  EXPECT_GT(o.distance(), 0.0f);
  EXPECT_NO_THROW(make_ray_generator(o.camera(), 16, 16));
  for (int i = 0; i < 500; ++i) o.zoom(-5.0f);
  EXPECT_LT(o.distance(), 100.0f * d0);
  o.zoom(NAN);
  EXPECT_TRUE(std::isfinite(o.distance()));
}

TEST(OrbitController, PanMovesCentreAndEyeTogetherInTheViewPlane) {
  OrbitController o(home());
  const Camera before = o.camera();
  const RayGenerator g = make_ray_generator(before, 400, 300);
  o.pan(40.0f, 0.0f, 300);
  const Camera after = o.camera();
  const vec3 moved = after.center - before.center;
  EXPECT_NEAR(glm::length((after.eye - after.center) - (before.eye - before.center)), 0.0f, 1e-3f);
  EXPECT_NEAR(glm::dot(moved, g.forward), 0.0f, 1e-3f);
  EXPECT_LT(glm::dot(moved, g.right), 0.0f);  // the scene follows the cursor to the right
  // 40 px at the centre's depth: 40 * 2 d tan(fov/2) / 300 world units.
  const float expect = 40.0f * 2.0f * dist(before) * std::tan(glm::radians(before.fov_deg * 0.5f)) / 300.0f;
  EXPECT_NEAR(glm::length(moved), expect, 1e-3f * expect);
  o.pan(0.0f, 30.0f, 300);  // dragging down moves the scene down: the centre goes up
  EXPECT_GT(glm::dot(o.camera().center - after.center, g.up), 0.0f);
}

TEST(OrbitController, ResetReturnsHomeAndSetCameraAdoptsAKeyframe) {
  OrbitController o(home());
  o.orbit(100.0f, 30.0f);
  o.zoom(3.0f);
  o.pan(10.0f, 10.0f, 100);
  o.reset();
  EXPECT_NEAR(glm::length(o.camera().eye - home().eye), 0.0f, 1e-2f);
  EXPECT_NEAR(glm::length(o.camera().center - home().center), 0.0f, 1e-4f);
  Camera k = home();
  k.eye = k.center + vec3(0.0f, 0.0f, 300.0f);
  o.set_camera(k);
  EXPECT_NEAR(glm::length(o.camera().eye - k.eye), 0.0f, 1e-2f);
}

TEST(OrbitController, OrthographicZoomScalesTheViewHeight) {
  Camera h = home();
  h.projection = Projection::Orthographic;
  OrbitController o(h);
  o.zoom(2.0f);
  EXPECT_NEAR(o.camera().height, h.height * 0.81f, 1e-3f * h.height);
  EXPECT_EQ(o.camera().projection, Projection::Orthographic);
}

}  // namespace
}  // namespace sl::viewer
