// Per-view visibility order of the occupancy geometry (paper §6.2, Alg. 3; DESIGN.md "Occupancy geometry and
// visibility order"): a depth-first, front-to-back traversal of the tree that lists every emitting node twice,
// FRONT before its children and BACK after them (a leaf's two entries are adjacent). Rasterizing boxes in this
// order makes a small box's class override the enclosing box's class over its extent (paper Fig. 5).
#pragma once

#include <cstdint>
#include <vector>

#include "core/scene/camera.h"
#include "core/util/config.h"
#include "core/util/math.h"
#include "core/occupancy/occupancy_geometry.h"
#include "core/occupancy/occupancy_tree.h"

namespace sl {

enum class Face : std::uint32_t { Front = 0, Back = 1 };

// One entry of the order: rasterize box `box` taking its front faces (ENTRY events) or its back
// faces (EXIT events). Plain data.
struct VisibilityEntry {
  std::uint32_t box = 0;
  Face face = Face::Front;
};
static_assert(sizeof(VisibilityEntry) == 8, "VisibilityEntry layout");

// What the order depends on: the eye position (perspective), or the view direction (orthographic:
// the eye at infinity along -forward).
struct ViewPoint {
  vec3 eye{0.0f};
  vec3 forward{0.0f, 0.0f, -1.0f};
  bool orthographic = false;
};
ViewPoint view_point(const RayGenerator& gen);

// Seed 002 (Mitra & Bose): child i in front-to-back order is octant XOR kOctantOrder[i], where bit a
// of `octant` is set when the node centre lies on the + side of the eye along axis a (bit 0 = x).
// kOctantOrder[0] = 7 makes the first child the one on the eye's side of all three split planes.
inline constexpr std::uint32_t kOctantOrder[8] = {7, 6, 5, 3, 4, 2, 1, 0};

SL_HOST_DEVICE inline std::uint32_t view_octant(const ViewPoint& v, const vec3& center) {
  std::uint32_t o = 0;
  for (int a = 0; a < 3; ++a) {
    // Eye on the + side (or on the plane) -> bit clear; matches segment_rules.py (eye >= centre).
    const bool centre_above = v.orthographic ? v.forward[a] > 0.0f : !(v.eye[a] >= center[a]);
    o |= centre_above ? (1u << a) : 0u;
  }
  return o;
}

// Alg. 3 over the geometry's (possibly truncated) tree. Subtrees wholly outside the volume are skipped.
std::vector<VisibilityEntry> build_visibility_order(const OccupancyTree& tree, const OccupancyGeometry& geometry,
                                                    const ViewPoint& view);

}  // namespace sl
