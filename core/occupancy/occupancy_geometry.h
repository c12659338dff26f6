// View-independent occupancy geometry (paper §6.1, Alg. 2; DESIGN.md "Occupancy geometry and visibility order"):
// nested boxes emitted breadth first wherever a node's class differs from its parent's. Regenerated only when
// occupancy changes (TF, labels, tree growth), reused across views.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/occupancy/occupancy_class.h"
#include "core/occupancy/occupancy_tree.h"
#include "core/util/ray.h"

namespace sl {

// One emitted box. Plain data, 32 bytes (the GL side uploads it; note std430 pads vec3 to 16 bytes,
// so a shader reads it as floats, not as two vec3).
struct OccupancyBox {
  Box3 box;                     // world space, clipped to the volume box
  OccupancyClass cls = OccupancyClass::Invalid;
  OccupancyClass parent_cls = OccupancyClass::Invalid;  // Invalid for the root (Alg. 2)
  std::uint8_t depth = 0;
  std::uint8_t pad = 0;
  std::uint32_t node = 0;       // index in OccupancyTree::nodes()
};
static_assert(sizeof(OccupancyBox) == 32, "OccupancyBox layout");

struct OccupancyGeometry {
  static constexpr std::uint32_t kNoBox = 0xFFFFFFFFu;
  std::vector<OccupancyBox> boxes;       // Alg. 2 order: coarse before fine
  std::vector<std::uint32_t> node_box;   // per tree node slot: its box, or kNoBox
  // Nodes at this depth act as leaves (the box budget cut the traversal there); an inner node cut off
  // takes its conservative class (NON_EMPTY if anything below is, else UNKNOWN if anything is, else
  // EMPTY), so a budget coarsens the lists but never turns anything non-empty into EMPTY.
  int depth_limit = OccupancyTree::kMaxLevels;
  bool truncated = false;
  std::uint64_t tree_revision = 0;  // OccupancyTree::revision() it was built from
};

// Alg. 2. box_budget = 0: unlimited; otherwise at most max(box_budget, 1) boxes, cutting the tree at
// the deepest level that fits. Nodes wholly outside the volume emit nothing.
OccupancyGeometry build_occupancy_geometry(const OccupancyTree& tree, std::size_t box_budget = 0);

// The class a node has in the geometry's (possibly truncated) tree, and whether it acts as a leaf.
OccupancyClass effective_class(const OccupancyTree& tree, const OccupancyGeometry& g, std::uint32_t node);
bool effective_leaf(const OccupancyTree& tree, const OccupancyGeometry& g, std::uint32_t node);

// `g` with each sampled box (NON_EMPTY or UNKNOWN) inside EMPTY replaced by the sampled leaves of
// its subtree, one box each inside EMPTY, wherever they are at most four times the boxes of that
// subtree (so never more than four times the boxes of `g`). The EMPTY boxes nested in it go: the leaves cover the
// same sampled region (each with its own class), so rays take the same samples. What changes is the
// lists' work: a ray meets leaves alone (an ENTRY and an EXIT each, appended as they come) instead
// of a box and the EMPTY boxes cut out of it, whose faces coincide with its own and with each other's
// and are merged event by event (Alg. 5's same-depth rules); and tighten_leaf_boxes can shrink the
// leaves, where it cannot shrink an inner box. Boxes breadth first, as Alg. 2's.
OccupancyGeometry flatten_sparse_subtrees(const OccupancyTree& tree, const OccupancyGeometry& g);

struct VoxelMaskView;

// `g` with each NON_EMPTY box of an (effective) leaf node shrunk to the trilinear cells of `mask` set
// inside it, a quarter voxel to spare on each side (a face of the volume stays where it is), and one
// without any set cell made empty (zero extent). Under the mask the caster fetches no sample whose
// cell bit is clear, and every sample whose bit is set lies in the shrunk box, so lists built from
// the result take the same samples and give the same image, with shorter spans to scan (thin
// structures fill a fraction of their blocks). Inner boxes keep their extent, so the boxes still nest.
// `mask` must be on the volume's voxel grid (world origin at the corner of voxel 0).
OccupancyGeometry tighten_leaf_boxes(const OccupancyTree& tree, const OccupancyGeometry& g, const VoxelMaskView& mask);

// The leaves of the tree cut at depth_limit, clipped to the volume (wholly outside ones dropped), with
// their effective classes (parent_cls = Invalid). The brute-force truth for tests, and the
// "non-empty bricks" of the bounding-geometry baseline.
std::vector<OccupancyBox> leaf_boxes(const OccupancyTree& tree, int depth_limit = OccupancyTree::kMaxLevels);

}  // namespace sl
