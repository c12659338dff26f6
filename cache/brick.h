// Multiresolution bricked volume layout (DESIGN.md "Data model") and the 64-bit brick id the ray caster reports
// in its unified misses (paper §8.2). Plain data, compiled by the CPU backend and by nvcc.
//
// Conventions (they make level-of-detail sampling consistent across levels):
//  - Level 0 is full resolution. Level l has dims ceil(dims / 2^l) and voxel spacing spacing * 2^l;
//    its voxel i is centred at world (i + 0.5) * spacing * 2^l, so level-l voxel i covers exactly the
//    world span of level-0 voxels [i * 2^l, (i + 1) * 2^l) — the 2^l children its value is the mean of.
//    Levels continue until one brick holds the whole level.
//  - A brick holds B³ payload voxels (B = 8, 16, 32 or 64) plus a 1-voxel apron on every side, stored
//    as (B + 2)³ voxels, x fastest. Stored voxel s (0 .. B + 1 per axis) of brick b is level voxel
//    b * B - 1 + s, clamped to the level's dims (clamp to edge, as DenseGrid samples), so trilinear
//    sampling anywhere in the payload never leaves the brick.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/util/config.h"
#include "core/util/math.h"
#include "core/scene/volume.h"

namespace sl {

// Levels 0 .. 14 are usable; level 15 is reserved so that the all-ones id can never be a real brick.
inline constexpr int kMaxBrickLevels = 15;
inline constexpr int kDefaultBrickSize = 32;
inline constexpr int kBrickApron = 1;

// Bit split of a BrickId, low to high: bx 20 bits | by 20 bits | bz 20 bits | level 4 bits.
// 2^20 bricks per axis is over 8 M voxels per axis even at B = 8.
struct BrickId {
  static constexpr int kAxisBits = 20;
  static constexpr std::uint64_t kAxisMask = (std::uint64_t(1) << kAxisBits) - 1;
  static constexpr std::uint64_t kInvalidBits = ~std::uint64_t(0);

  std::uint64_t bits = kInvalidBits;

  SL_HOST_DEVICE static BrickId pack(int level, ivec3 b) {
    BrickId id;
    id.bits = std::uint64_t(std::uint32_t(b.x)) | (std::uint64_t(std::uint32_t(b.y)) << kAxisBits) |
              (std::uint64_t(std::uint32_t(b.z)) << (2 * kAxisBits)) |
              (std::uint64_t(std::uint32_t(level)) << (3 * kAxisBits));
    return id;
  }
  SL_HOST_DEVICE static BrickId invalid() { return BrickId{}; }

  SL_HOST_DEVICE int level() const { return int(bits >> (3 * kAxisBits)); }
  SL_HOST_DEVICE ivec3 coord() const {
    return ivec3(int(bits & kAxisMask), int((bits >> kAxisBits) & kAxisMask),
                 int((bits >> (2 * kAxisBits)) & kAxisMask));
  }
  SL_HOST_DEVICE bool valid() const { return bits != kInvalidBits; }
  // The brick one level coarser that covers this one (each level halves voxels; bricks keep B).
  SL_HOST_DEVICE BrickId parent() const { return pack(level() + 1, coord() / 2); }

  SL_HOST_DEVICE friend bool operator==(BrickId a, BrickId b) { return a.bits == b.bits; }
  SL_HOST_DEVICE friend bool operator!=(BrickId a, BrickId b) { return a.bits != b.bits; }
  SL_HOST_DEVICE friend bool operator<(BrickId a, BrickId b) { return a.bits < b.bits; }
};
static_assert(sizeof(BrickId) == 8, "BrickId crosses to the GPU as one 64-bit word");

// For std::unordered_map/set on the host.
struct BrickIdHash {
  std::size_t operator()(BrickId id) const {
    std::uint64_t z = id.bits * 0x9E3779B97F4A7C15ull;
    return std::size_t(z ^ (z >> 32));
  }
};

// "level 2 brick (3, 4, 5)", for reports and errors.
std::string to_string(BrickId id);

struct WorldBox {
  vec3 lo{0.0f}, hi{0.0f};
};

// Geometry of the brick pyramid. Plain, fixed-size, copyable to a device.
struct BrickLayout {
  ivec3 level_dims[kMaxBrickLevels];    // voxels per axis at each level
  ivec3 level_bricks[kMaxBrickLevels];  // bricks per axis at each level
  vec3 spacing{1.0f};              // level-0 voxel spacing
  vec3 inv_spacing{1.0f};          // 1 / spacing, computed as DenseGrid users do (bit-identical sampling)
  std::int32_t brick_size = kDefaultBrickSize;  // B
  std::int32_t levels = 0;

  // Host-only constructor. Throws InputError("--brick", ...) when B is not 8, 16, 32 or 64, and
  // InputError(origin, ...) when the volume needs more than kMaxBrickLevels levels or 2^20 bricks per axis.
  static BrickLayout make(ivec3 dims, vec3 spacing, int brick_size = kDefaultBrickSize,
                          const std::string& origin = "volume");
  static BrickLayout make(const VolumeDesc& d, int brick_size = kDefaultBrickSize,
                          const std::string& origin = "volume") {
    return make(d.dims, d.spacing, brick_size, origin);
  }

  SL_HOST_DEVICE int stored_size() const { return brick_size + 2 * kBrickApron; }
  SL_HOST_DEVICE std::uint32_t stored_voxels() const {
    const std::uint32_t s = std::uint32_t(stored_size());
    return s * s * s;
  }
  SL_HOST_DEVICE ivec3 dims(int level) const { return level_dims[level]; }
  SL_HOST_DEVICE ivec3 bricks(int level) const { return level_bricks[level]; }
  SL_HOST_DEVICE std::uint64_t brick_count(int level) const {
    const ivec3 b = level_bricks[level];
    return std::uint64_t(b.x) * std::uint64_t(b.y) * std::uint64_t(b.z);
  }
  // Exact: scaling by a power of two only changes the exponent.
  SL_HOST_DEVICE vec3 level_spacing(int level) const { return spacing * float(1 << level); }
  // inv_spacing / 2^level without a division: 2^-level is exact, so the product is the same real
  // number as the quotient, rounded the same way.
  SL_HOST_DEVICE vec3 level_inv_spacing(int level) const { return inv_spacing * (1.0f / float(1 << level)); }

  SL_HOST_DEVICE bool contains(BrickId id) const {
    if (!id.valid() || id.level() >= levels) return false;
    const ivec3 c = id.coord(), n = level_bricks[id.level()];
    return c.x < n.x && c.y < n.y && c.z < n.z;
  }
  // Level voxel of the brick's first payload voxel (stored voxel 1).
  SL_HOST_DEVICE ivec3 brick_origin(BrickId id) const { return id.coord() * brick_size; }

  // The brick and the payload-local voxel (0 .. B-1) holding level voxel v (0 <= v < dims(level)).
  SL_HOST_DEVICE BrickId brick_of_voxel(int level, ivec3 v) const { return BrickId::pack(level, v / brick_size); }
  SL_HOST_DEVICE ivec3 local_voxel(ivec3 v) const { return v - (v / brick_size) * brick_size; }

  // The brick whose payload holds world position p at `level`; p is clamped into the volume, so a
  // sample on the far boundary maps to the last brick, as DenseGrid clamps it to the last voxel.
  SL_HOST_DEVICE BrickId brick_at(int level, const vec3& p) const {
    const vec3 u = p * level_inv_spacing(level);
    const ivec3 d = level_dims[level];
    ivec3 v = floor_to_int(u);
    v = glm::clamp(v, ivec3(0), d - 1);
    return brick_of_voxel(level, v);
  }

  // World box of a brick's payload, clipped to the volume box [0, dims * spacing] (the last level
  // voxel of an odd axis reaches past the volume; rays never sample there).
  SL_HOST_DEVICE WorldBox brick_box(BrickId id) const {
    const vec3 s = level_spacing(id.level());
    const ivec3 o = brick_origin(id);
    const vec3 extent = vec3(level_dims[0]) * spacing;
    WorldBox box;
    box.lo = glm::min(vec3(o) * s, extent);
    box.hi = glm::min(vec3(o + brick_size) * s, extent);
    return box;
  }

  // Index of stored voxel s (0 .. B + 1 per axis) within a brick's (B + 2)³ array.
  SL_HOST_DEVICE std::uint32_t stored_index(ivec3 s) const {
    const std::uint32_t n = std::uint32_t(stored_size());
    return (std::uint32_t(s.z) * n + std::uint32_t(s.y)) * n + std::uint32_t(s.x);
  }
};
static_assert(sizeof(BrickLayout) == 2 * kMaxBrickLevels * 12 + 2 * 12 + 8, "BrickLayout is plain data");

// The culling blocks (edge `block` level voxels; `block` divides the brick size) of a brick's payload
// that lie inside its level, as block coordinates of that level, x fastest: the blocks whose metadata
// the brick's voxels (or a source's bounds) give.
std::vector<ivec3> brick_culling_blocks(const BrickLayout& layout, BrickId id, int block);

}  // namespace sl
