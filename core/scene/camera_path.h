// Camera paths for benchmarks and recordings: keyframes interpolated smoothly (positions on a
// Catmull-Rom spline, up vectors without flips), and generated orbits.
#pragma once

#include <string>
#include <vector>

#include "core/scene/camera.h"

namespace sl {

struct CameraPath {
  std::vector<Camera> keyframes;  // eye, center, up, fov_deg (projection of the first applies to all)
  int frames = 0;                 // frames rendered along the whole path

  // Camera of frame i in [0, frames): keyframes spread evenly over the frames.
  Camera at(int i) const;
};

// `{"frames":N,"keyframes":[{"eye":[..],"center":[..],"up":[..],"fov_deg":30},...]}`;
// InputError names the file.
CameraPath load_camera_path(const std::string& path);
CameraPath parse_camera_path(const std::string& json_text, const std::string& origin);
std::string camera_path_to_json(const CameraPath& p);

// A full orbit of `frames` frames around the volume centre, starting at the default view.
CameraPath orbit_path(const vec3& extent, int frames);
// The orbit while the distance to the centre oscillates `cycles` times between the default view's
// and `closest` times it, so the level of detail changes back and forth (soak tests).
CameraPath orbit_zoom_path(const vec3& extent, int frames, int cycles = 3, float closest = 0.25f);
// From the default view straight towards the centre, the distance shrinking geometrically to
// `closest` times the start's (convergence under zoom, prefetch measurements).
CameraPath zoom_in_path(const vec3& extent, int frames, float closest = 0.2f);
// Linear extrapolation of the next camera from the previous and the current one (prefetch along the
// camera's motion): eye and centre continue by the same step, up and the lens stay.
Camera extrapolate_camera(const Camera& previous, const Camera& current);

}  // namespace sl
