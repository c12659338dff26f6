#include "core/scene/camera_path.h"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>

#include "core/util/error.h"
#include "core/util/json_util.h"

namespace sl {
namespace {

// Centripetal-free uniform Catmull-Rom through p1..p2 (p0, p3 are the neighbours).
vec3 catmull_rom(const vec3& p0, const vec3& p1, const vec3& p2, const vec3& p3, float t) {
  const float t2 = t * t, t3 = t2 * t;
  return 0.5f * ((2.0f * p1) + (-p0 + p2) * t + (2.0f * p0 - 5.0f * p1 + 4.0f * p2 - p3) * t2 +
                 (-p0 + 3.0f * p1 - 3.0f * p2 + p3) * t3);
}

}  // namespace

Camera CameraPath::at(int i) const {
  SL_CHECK(!keyframes.empty());
  const int n = int(keyframes.size());
  if (n == 1 || frames <= 1) return keyframes.front();
  const float u = float(i) / float(frames - 1) * float(n - 1);  // position along the keyframes
  int k = int(std::floor(u));
  if (k >= n - 1) k = n - 2;
  if (k < 0) k = 0;
  const float t = u - float(k);
  auto key = [&](int j) -> const Camera& { return keyframes[std::size_t(std::clamp(j, 0, n - 1))]; };
  Camera c = keyframes.front();
  c.eye = catmull_rom(key(k - 1).eye, key(k).eye, key(k + 1).eye, key(k + 2).eye, t);
  c.center = catmull_rom(key(k - 1).center, key(k).center, key(k + 1).center, key(k + 2).center, t);
  c.fov_deg = key(k).fov_deg + t * (key(k + 1).fov_deg - key(k).fov_deg);
  c.height = key(k).height + t * (key(k + 1).height - key(k).height);
  // Up: interpolate, then make it orthogonal to the view so it never flips through the view axis.
  vec3 up = glm::normalize(key(k).up) * (1.0f - t) + glm::normalize(key(k + 1).up) * t;
  const vec3 fwd = glm::normalize(c.center - c.eye);
  up -= glm::dot(up, fwd) * fwd;
  c.up = glm::length(up) > 1e-6f ? glm::normalize(up) : key(k).up;
  return c;
}

CameraPath parse_camera_path(const std::string& text, const std::string& origin) {
  const nlohmann::json j = parse_json(text, origin);
  if (!j.is_object() || !j.contains("keyframes") || !j["keyframes"].is_array() || j["keyframes"].empty()) {
    throw InputError(origin, "expected an object with a non-empty \"keyframes\" array");
  }
  CameraPath p;
  for (const auto& k : j["keyframes"]) p.keyframes.push_back(camera_from_json(k, origin));
  const float frames = j.contains("frames") ? json_number(j, "frames", origin) : float(p.keyframes.size());
  if (!(frames >= 1.0f && frames <= 1e6f) || frames != std::floor(frames)) {
    throw InputError(origin, "\"frames\" must be a whole number between 1 and 1000000");
  }
  p.frames = int(frames);
  return p;
}

CameraPath load_camera_path(const std::string& path) { return parse_camera_path(read_file_text(path), path); }

std::string camera_path_to_json(const CameraPath& p) {
  nlohmann::json j;
  j["frames"] = p.frames;
  j["keyframes"] = nlohmann::json::array();
  for (const Camera& c : p.keyframes) j["keyframes"].push_back(nlohmann::json::parse(camera_to_json(c)));
  return j.dump(2);
}

namespace {

constexpr float kPi = 3.14159265f;

// The orbit at frame i of n, with the eye at `scale` times the default distance.
Camera orbit_camera(const Camera& start, int i, int n, float scale) {
  const vec3 offset = start.eye - start.center;
  const float radius = std::sqrt(offset.x * offset.x + offset.z * offset.z);
  const float phase = std::atan2(offset.z, offset.x);
  const float a = phase + 2.0f * kPi * float(i) / float(n);
  Camera c = start;
  c.eye = start.center + scale * vec3(radius * std::cos(a), offset.y, radius * std::sin(a));
  return c;
}

}  // namespace

CameraPath orbit_path(const vec3& extent, int frames) { return orbit_zoom_path(extent, frames, 0, 1.0f); }

CameraPath orbit_zoom_path(const vec3& extent, int frames, int cycles, float closest) {
  const Camera start = default_camera(extent);
  CameraPath p;
  p.frames = std::max(frames, 1);
  // One keyframe per frame: the spline then passes exactly through every frame.
  for (int i = 0; i < p.frames; ++i) {
    const float u = float(i) / float(p.frames);
    const float scale = closest + (1.0f - closest) * 0.5f * (1.0f + std::cos(2.0f * kPi * float(cycles) * u));
    p.keyframes.push_back(orbit_camera(start, i, p.frames, scale));
  }
  return p;
}

CameraPath zoom_in_path(const vec3& extent, int frames, float closest) {
  const Camera start = default_camera(extent);
  CameraPath p;
  p.frames = std::max(frames, 1);
  for (int i = 0; i < p.frames; ++i) {
    const float u = p.frames > 1 ? float(i) / float(p.frames - 1) : 0.0f;
    Camera c = start;
    c.eye = start.center + std::pow(closest, u) * (start.eye - start.center);
    p.keyframes.push_back(c);
  }
  return p;
}

Camera extrapolate_camera(const Camera& previous, const Camera& current) {
  Camera c = current;
  c.eye = current.eye + (current.eye - previous.eye);
  c.center = current.center + (current.center - previous.center);
  if (glm::length(c.center - c.eye) < 1e-6f * (1.0f + glm::length(current.center - current.eye))) return current;
  return c;
}

}  // namespace sl
