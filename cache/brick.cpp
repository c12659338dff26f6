#include "cache/brick.h"

#include "core/util/error.h"

namespace sl {

std::string to_string(BrickId id) {
  if (!id.valid()) return "invalid brick";
  const ivec3 c = id.coord();
  return "level " + std::to_string(id.level()) + " brick (" + std::to_string(c.x) + ", " +
         std::to_string(c.y) + ", " + std::to_string(c.z) + ")";
}

std::vector<ivec3> brick_culling_blocks(const BrickLayout& layout, BrickId id, int block) {
  SL_CHECK(block > 0 && layout.brick_size % block == 0);
  const int per = layout.brick_size / block;
  const ivec3 dims = layout.dims(id.level());
  std::vector<ivec3> blocks;
  blocks.reserve(std::size_t(per) * per * per);
  for (int z = 0; z < per; ++z)
    for (int y = 0; y < per; ++y)
      for (int x = 0; x < per; ++x) {
        const ivec3 c = id.coord() * per + ivec3(x, y, z);
        if (c.x * block < dims.x && c.y * block < dims.y && c.z * block < dims.z) blocks.push_back(c);
      }
  return blocks;
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
