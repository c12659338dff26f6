#include "cache/brick.h"

#include "core/util/error.h"

namespace sl {

std::string to_string(BrickId id) {
  if (!id.valid()) return "invalid brick";
  const ivec3 c = id.coord();
  return "level " + std::to_string(id.level()) + " brick (" + std::to_string(c.x) + ", " +
         std::to_string(c.y) + ", " + std::to_string(c.z) + ")";
}

BrickLayout BrickLayout::make(ivec3 dims, vec3 spacing, int brick_size, const std::string& origin) {
  if (brick_size != 8 && brick_size != 16 && brick_size != 32 && brick_size != 64) {
    throw InputError("--brick", "brick size " + std::to_string(brick_size) + " is not one of 8, 16, 32, 64");
  }
  for (int a = 0; a < 3; ++a) {
    if (dims[a] <= 0) throw InputError(origin, "dimension " + std::to_string(a) + " must be positive");
    if (!(spacing[a] > 0.0f)) throw InputError(origin, "spacing must be positive");
  }
  BrickLayout l;
  l.spacing = spacing;
  l.inv_spacing = 1.0f / spacing;  // the expression the CPU and CUDA renderers use for DenseGrid
  l.brick_size = brick_size;
  ivec3 d = dims;
  for (int level = 0;; ++level) {
    if (level >= kMaxBrickLevels) {
      throw InputError(origin, "volume needs more than " + std::to_string(kMaxBrickLevels) +
                                   " levels of " + std::to_string(brick_size) + "^3 bricks");
    }
    l.level_dims[level] = d;
    l.level_bricks[level] = (d + brick_size - 1) / brick_size;
    for (int a = 0; a < 3; ++a) {
      if (std::uint64_t(l.level_bricks[level][a]) > BrickId::kAxisMask + 1) {
        throw InputError(origin, "more than 2^20 bricks along axis " + std::to_string(a));
      }
    }
    l.levels = level + 1;
    if (d.x <= brick_size && d.y <= brick_size && d.z <= brick_size) break;
    d = (d + 1) / 2;  // ceil(dims / 2^l) == ceil(ceil(dims / 2^(l-1)) / 2)
  }
  for (int level = l.levels; level < kMaxBrickLevels; ++level) {
    l.level_dims[level] = ivec3(0);
    l.level_bricks[level] = ivec3(0);
  }
  return l;
}

}  // namespace sl
