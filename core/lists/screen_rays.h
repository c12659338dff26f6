// The screen side of the CPU list builder (core/lists/segment_list_builder.h) and of the GL builder's
// primitives: a box's conservative pixel rectangle, and a tile's rays as structure of arrays.
#pragma once

#include "core/scene/camera.h"
#include "core/util/parallel.h"
#include "core/util/ray.h"

namespace sl {

// Inclusive pixel rectangle; empty when x0 > x1 or y0 > y1.
struct ScreenRect {
  int x0 = 0, y0 = 0, x1 = -1, y1 = -1;
  bool empty() const { return x0 > x1 || y0 > y1; }
};

// Every pixel whose ray can hit `box` at some t > 0 lies in this rectangle: the pixels whose centres
// lie within the projected corners' bounds (0.01 pixel to spare for float rounding); the full screen
// when the box holds the eye or straddles the eye plane (perspective); empty when the box lies wholly
// behind the eye plane. The GL builder uses the same rectangle for its primitive.
ScreenRect conservative_screen_rect(const Box3& box, const RayGenerator& gen);

namespace detail {

// A direction component's reciprocal for the slab tests (segment_list_builder.h): +inf for +-0, so that an axis the ray is parallel to
// leaves [t0, t1] as it is when the origin lies within the slab and empties it otherwise — the
// `d == 0` branch of intersect(), without the branch.
inline float slab_reciprocal(float d) { return d == 0.0f ? __builtin_huge_valf() : 1.0f / d; }

// The rays of a kTileSize x kTileSize screen tile (pixel k = ly * kTileSize + lx) as structure of
// arrays: origins and slab_reciprocal'd directions, bit for bit gen.ray()'s, and the directions
// themselves where `dir` is given; zero past tile.x1, tile.y1.
void tile_rays(const RayGenerator& gen, const ScreenRect& tile, float (*origin)[kTileSize * kTileSize],
               float (*inv_dir)[kTileSize * kTileSize], float (*dir)[kTileSize * kTileSize] = nullptr);

}  // namespace detail

}  // namespace sl
