#include "core/scene/camera.h"

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/util/error.h"
#include "core/util/json_util.h"

namespace sl {

Camera parse_camera(const std::string& text, const std::string& origin) {
  return camera_from_json(parse_json(text, origin), origin);
}

Camera camera_from_json(const nlohmann::json& j, const std::string& origin) {
  if (!j.is_object()) throw InputError(origin, "camera must be a JSON object");
  Camera c;
  c.eye = json_vec3(j, "eye", origin, true);
  c.center = json_vec3(j, "center", origin, true);
  c.up = j.contains("up") ? json_vec3(j, "up", origin, true) : vec3(0, 1, 0);
  if (j.contains("projection")) {
    const auto& p = j["projection"];
    if (!p.is_string()) throw InputError(origin, "\"projection\" must be a string");
    const std::string s = p.get<std::string>();
    if (s == "perspective") {
      c.projection = Projection::Perspective;
    } else if (s == "orthographic") {
      c.projection = Projection::Orthographic;
    } else {
      throw InputError(origin, "unknown projection '" + s + "' (expected perspective or orthographic)");
    }
  }
  if (j.contains("fov_deg")) c.fov_deg = json_number(j, "fov_deg", origin);
  if (j.contains("height")) c.height = json_number(j, "height", origin);
  if (c.projection == Projection::Perspective && !(c.fov_deg > 0.0f && c.fov_deg < 180.0f)) {
    throw InputError(origin, "\"fov_deg\" must be in (0, 180)");
  }
  if (c.projection == Projection::Orthographic && !(c.height > 0.0f)) {
    throw InputError(origin, "\"height\" must be positive for an orthographic camera");
  }
  make_ray_generator(c, 1, 1, origin);  // rejects degenerate frames
  return c;
}

Camera load_camera(const std::string& path) { return parse_camera(read_file_text(path), path); }

std::string camera_to_json(const Camera& c) {
  nlohmann::json j;
  j["eye"] = {c.eye.x, c.eye.y, c.eye.z};
  j["center"] = {c.center.x, c.center.y, c.center.z};
  j["up"] = {c.up.x, c.up.y, c.up.z};
  j["fov_deg"] = c.fov_deg;
  j["projection"] = c.projection == Projection::Perspective ? "perspective" : "orthographic";
  if (c.projection == Projection::Orthographic) j["height"] = c.height;
  return j.dump(2);
}

Camera default_camera(const vec3& extent) {
  Camera c;
  c.center = 0.5f * extent;
  const float radius = 0.5f * glm::length(extent);
  const vec3 dir = glm::normalize(vec3(0.55f, 0.45f, 1.0f));
  c.fov_deg = 30.0f;
  // Distance at which the bounding sphere fits the vertical field of view, with a small margin.
  const float dist = 1.05f * radius / std::sin(glm::radians(0.5f * c.fov_deg));
  c.eye = c.center + dist * dir;
  c.up = vec3(0.0f, 1.0f, 0.0f);
  c.height = 2.1f * radius;
  return c;
}

RayGenerator make_ray_generator(const Camera& c, int width, int height, const std::string& origin) {
  RayGenerator g;
  const vec3 view = c.center - c.eye;
  if (!(glm::length(view) > 0.0f)) throw InputError(origin, "camera eye and center coincide");
  g.forward = glm::normalize(view);
  const vec3 r = glm::cross(g.forward, c.up);
  if (!(glm::length(r) > 1e-6f * glm::length(c.up))) {
    throw InputError(origin, "camera up vector is zero or parallel to the view direction");
  }
  g.right = glm::normalize(r);
  g.up = glm::cross(g.right, g.forward);
  g.eye = c.eye;
  g.width = width;
  g.height = height;
  g.aspect = float(width) / float(height);
  g.orthographic = c.projection == Projection::Orthographic;
  g.half_h = g.orthographic ? 0.5f * c.height : std::tan(glm::radians(0.5f * c.fov_deg));
  return g;
}

}  // namespace sl
