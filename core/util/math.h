// GLM, included one way everywhere. Under nvcc, GLM_FORCE_CUDA must NOT be defined (its CUDA version
// check rejects CUDA 13); GLM then marks its functions __host__ __device__ by itself (DESIGN.md "Conventions").
#pragma once

#include <glm/glm.hpp>

#include "core/util/config.h"

namespace sl {
using glm::ivec3;
using glm::uvec3;
using glm::vec2;
using glm::vec3;
using glm::vec4;

// int(floor(x)) for |x| < 2^31, without floorf: on baseline x86-64 (no SSE4.1 roundss) floorf is a
// libm call, which the per-sample brick lookups out of core paid on every coordinate.
SL_HOST_DEVICE SL_INLINE int floor_to_int(float x) {
  const int i = int(x);
  return float(i) > x ? i - 1 : i;
}
SL_HOST_DEVICE SL_INLINE ivec3 floor_to_int(const vec3& u) { return ivec3(floor_to_int(u.x), floor_to_int(u.y), floor_to_int(u.z)); }
}  // namespace sl
