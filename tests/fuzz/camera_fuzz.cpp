// Camera JSON (core/camera.cpp): parsed; what parses is written back and must read back the same
// (the view height only where it is used), and a ray generator is made from it as render does
// (refusing a degenerate view is an InputError).
#include <cstdint>

#include "core/camera.h"
#include "core/error.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  sl::Camera c;
  try {
    c = sl::parse_camera(std::string(sl::fuzz::as_text(data, size)), "camera.json");
  } catch (const sl::InputError&) {
    return 0;
  }
  const sl::Camera b = sl::parse_camera(sl::camera_to_json(c), "written");
  // The view height is written only for orthographic cameras, the one projection that uses it.
  const bool ortho = c.projection == sl::Projection::Orthographic;
  if (b.eye != c.eye || b.center != c.center || b.up != c.up || b.fov_deg != c.fov_deg ||
      (ortho && b.height != c.height) || b.projection != c.projection) {
    std::abort();
  }
  try {
    sl::make_ray_generator(c, 64, 48, "camera.json");
  } catch (const sl::InputError&) {
  }
  return 0;
}
