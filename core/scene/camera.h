// Camera description (the camera JSON of DESIGN.md "Ray casting") and the plain ray generator casters use.
#pragma once

#include <nlohmann/json_fwd.hpp>
#include <string>

#include "core/util/config.h"
#include "core/util/math.h"
#include "core/util/ray.h"

namespace sl {

enum class Projection { Perspective, Orthographic };

struct Camera {
  vec3 eye{0.0f, 0.0f, 1.0f};
  vec3 center{0.0f};
  vec3 up{0.0f, 1.0f, 0.0f};
  float fov_deg = 30.0f;    // vertical field of view (perspective)
  float height = 1.0f;      // world-space height of the view (orthographic)
  Projection projection = Projection::Perspective;

  bool operator==(const Camera&) const = default;
};

// Reads `{"eye":[..],"center":[..],"up":[..],"fov_deg":30,"projection":"perspective"|"orthographic",
// "height":h}`; throws InputError naming the file on any problem.
Camera load_camera(const std::string& path);
Camera parse_camera(const std::string& json_text, const std::string& origin);
// The same from an already parsed value (camera-path keyframes: re-serialising a value recurses once
// per nesting level, so a deeply nested file would overflow the stack).
Camera camera_from_json(const nlohmann::json& j, const std::string& origin);
std::string camera_to_json(const Camera& c);

// A default view of a volume box [0, extent]: looking at its centre from the front-right-top, framing it.
Camera default_camera(const vec3& extent);

// Plain per-frame ray generator: pixel (x, y), row 0 at the top, ray through the pixel centre.
struct RayGenerator {
  vec3 eye{0.0f};
  vec3 forward{0.0f, 0.0f, -1.0f};
  vec3 right{1.0f, 0.0f, 0.0f};
  vec3 up{0.0f, 1.0f, 0.0f};
  float half_h = 1.0f;  // tan(fov/2) for perspective; world half-height for orthographic
  float aspect = 1.0f;  // width / height
  int width = 1;
  int height = 1;
  bool orthographic = false;

  SL_HOST_DEVICE Ray ray(int x, int y) const {
    const float sx = (2.0f * (float(x) + 0.5f) / float(width) - 1.0f) * half_h * aspect;
    const float sy = (1.0f - 2.0f * (float(y) + 0.5f) / float(height)) * half_h;
    Ray r;
    if (orthographic) {
      r.origin = eye + sx * right + sy * up;
      r.dir = forward;
    } else {
      r.origin = eye;
      r.dir = glm::normalize(forward + sx * right + sy * up);
    }
    return r;
  }
};

// Throws InputError(origin, ...) for a degenerate camera (eye == center, up parallel to the view).
RayGenerator make_ray_generator(const Camera& c, int width, int height,
                                const std::string& origin = "camera");

}  // namespace sl
