// Camera JSON (core/scene/camera.cpp): parsed; what parses is written back and must read back the same
// (the view height only where it is used), and a ray generator is made from it as render does
// (refusing a degenerate view is an InputError).
#include "core/scene/camera.h"
#include "core/util/error.h"
#include "tests/fuzz/fuzz_util.h"

SL_FUZZ_TARGET(input) {
  const auto parsed = sl::fuzz::accepted([&] { return sl::parse_camera(std::string(input), "camera.json"); });
  if (!parsed) return;
  const sl::Camera& c = *parsed;
  const sl::Camera b = sl::parse_camera(sl::camera_to_json(c), "written");
  // The view height is written only for orthographic cameras, the one projection that uses it.
  const bool ortho = c.projection == sl::Projection::Orthographic;
  if (b.eye != c.eye || b.center != c.center || b.up != c.up || b.fov_deg != c.fov_deg ||
      (ortho && b.height != c.height) || b.projection != c.projection) {
    std::abort();
  }
  sl::fuzz::accepted([&] { return sl::make_ray_generator(c, 64, 48, "camera.json"); });
}
