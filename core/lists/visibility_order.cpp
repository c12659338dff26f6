#include "core/lists/visibility_order.h"

namespace sl {

ViewPoint view_point(const RayGenerator& gen) {
  return ViewPoint{gen.eye, gen.forward, gen.orthographic};
}

namespace {

struct OrderBuilder {
  const OccupancyTree& tree;
  const OccupancyGeometry& geometry;
  const ViewPoint& view;
  std::vector<VisibilityEntry>& out;

  // Alg. 3. Non-emitting nodes (class equal to the parent's) are traversed but list nothing.
  void visit(std::uint32_t n) {
    const std::uint32_t box = geometry.node_box[n];
    if (box != OccupancyGeometry::kNoBox) out.push_back({box, Face::Front});
    if (!effective_leaf(tree, geometry, n)) {
      const std::uint32_t octant = view_octant(view, tree.node_center(n));
      for (std::uint32_t i = 0; i < 8; ++i) {
        const std::uint32_t c = tree.child(n, int(octant ^ kOctantOrder[i]));
        if (!tree.outside(c)) visit(c);
      }
    }
    if (box != OccupancyGeometry::kNoBox) out.push_back({box, Face::Back});
  }
};

}  // namespace

std::vector<VisibilityEntry> build_visibility_order(const OccupancyTree& tree, const OccupancyGeometry& geometry,
                                                    const ViewPoint& view) {
  // The geometry must come from this tree as it is now (regenerate it after any occupancy change).
  SL_CHECK(geometry.tree_revision == tree.revision() && geometry.node_box.size() == tree.nodes().size());
  std::vector<VisibilityEntry> out;
  out.reserve(2 * geometry.boxes.size());
  OrderBuilder{tree, geometry, view, out}.visit(tree.root());
  return out;
}

}  // namespace sl
