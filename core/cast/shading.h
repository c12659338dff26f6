// Blinn–Phong lighting of volume samples (DESIGN.md "Lighting"): a headlight (the light
// along the view ray), the gradient of the reconstruction as the normal, and the parameters named and
// defaulted as VTK's vtkVolumeProperty (ambient 0.1, diffuse 0.7, specular 0.2, specular power 10), so
// images can be compared with VTK's shaded mapper. Plain data, SL_HOST_DEVICE: the kernels shade alike.
#pragma once

#include <cmath>

#include "core/util/config.h"
#include "core/util/math.h"

namespace sl {

struct Lighting {
  bool enabled = false;
  float ambient = 0.1f;
  float diffuse = 0.7f;
  float specular = 0.2f;
  float shininess = 10.0f;  // VTK's specular power
  // Gradient-magnitude guard (value units per world unit): below it the normal is noise (homogeneous
  // regions, where the gradient is ~0) and the sample keeps its unlit colour.
  float min_gradient = 0.0f;

  bool operator==(const Lighting&) const = default;
};

// The lit colour of a sample of colour `rgb` (not premultiplied) with reconstruction gradient `g` seen
// along `view_dir`. Two-sided (the normal faces the viewer), as VTK's volume shading; with a headlight
// the half vector is the light direction, so the specular term is (n·l)^shininess, white.
SL_HOST_DEVICE inline vec3 blinn_phong(const vec3& rgb, const vec3& g, const vec3& view_dir, const Lighting& l) {
  const float len = glm::length(g);
  if (!(len > l.min_gradient) || !(len > 0.0f)) return rgb;
  const float ndotl = fabsf(glm::dot(g, view_dir)) / len;
  const float spec = l.specular > 0.0f && ndotl > 0.0f ? l.specular * powf(ndotl, l.shininess) : 0.0f;
  return rgb * (l.ambient + l.diffuse * ndotl) + vec3(spec);
}

}  // namespace sl
