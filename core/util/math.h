// GLM, included one way everywhere. Under nvcc, GLM_FORCE_CUDA must NOT be defined (its CUDA version
// check rejects CUDA 13); GLM then marks its functions __host__ __device__ by itself (DESIGN.md "Conventions").
#pragma once

#include <glm/glm.hpp>

namespace sl {
using glm::ivec3;
using glm::uvec3;
using glm::vec2;
using glm::vec3;
using glm::vec4;
}  // namespace sl
