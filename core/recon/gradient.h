// The central-difference gradient (DESIGN.md "Ray casting": isosurface normals; Blinn–Phong shading), written
// once for every sampler: the dense in-core volume, the out-of-core virtual sampler and the CUDA
// texture-atlas sampler. The operation order is fixed here, so all of them give the same bits for the
// same samples.
#pragma once

#include "core/util/config.h"
#include "core/util/math.h"

namespace sl {

// (f(p + h_x) - f(p - h_x)) / 2h_x per axis, with `sample(q)` the reconstruction at world position q
// and h the step per axis in world units (one voxel of the level sampled).
template <class Sample>
SL_HOST_DEVICE vec3 central_difference_gradient(const vec3& p, const vec3& h, const Sample& sample) {
  const vec3 hx(h.x, 0, 0), hy(0, h.y, 0), hz(0, 0, h.z);
  return vec3((sample(p + hx) - sample(p - hx)) / (2.0f * h.x),
              (sample(p + hy) - sample(p - hy)) / (2.0f * h.y),
              (sample(p + hz) - sample(p - hz)) / (2.0f * h.z));
}

}  // namespace sl
