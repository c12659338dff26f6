#include "core/occupancy_geometry.h"

#include <algorithm>

namespace sl {

namespace {

// Class of a node when the tree is cut at its depth: a leaf keeps its class, a cut inner node takes
// the conservative class of its histogram.
OccupancyClass frontier_class(const OccupancyTree& t, std::uint32_t n) {
  return t.is_leaf(n) ? t.node(n).cls : conservative_class(t.node(n).count);
}

}  // namespace

OccupancyClass effective_class(const OccupancyTree& tree, const OccupancyGeometry& g, std::uint32_t node) {
  return tree.node(node).depth >= g.depth_limit ? frontier_class(tree, node) : tree.node(node).cls;
}

bool effective_leaf(const OccupancyTree& tree, const OccupancyGeometry& g, std::uint32_t node) {
  return tree.is_leaf(node) || tree.node(node).depth >= g.depth_limit;
}

OccupancyGeometry build_occupancy_geometry(const OccupancyTree& tree, std::size_t box_budget) {
  // Alg. 2 is a breadth-first queue; we keep its levels apart so that a budget can be applied as a
  // cut at a whole level: first count, per level d, the boxes the full traversal emits there (T[d])
  // and the boxes it would emit if the tree were cut at d (F[d]).
  std::vector<std::vector<std::uint32_t>> level{{tree.root()}};
  std::vector<std::size_t> full_count, cut_count;
  auto parent_class = [&](std::uint32_t n) {
    const std::uint32_t p = tree.node(n).parent;
    return p == OccupancyTree::kNone ? OccupancyClass::Invalid : tree.node(p).cls;
  };
  for (std::size_t d = 0; !level[d].empty(); ++d) {
    std::vector<std::uint32_t> next;
    std::size_t t = 0, f = 0;
    for (std::uint32_t n : level[d]) {
      const OccupancyClass pc = parent_class(n);
      t += tree.node(n).cls != pc ? 1 : 0;
      f += frontier_class(tree, n) != pc ? 1 : 0;
      if (tree.is_leaf(n)) continue;
      for (int k = 0; k < 8; ++k) {  // children in a fixed order (not visibility order)
        const std::uint32_t c = tree.child(n, k);
        if (!tree.outside(c)) next.push_back(c);
      }
    }
    full_count.push_back(t);
    cut_count.push_back(f);
    level.push_back(std::move(next));
  }
  level.pop_back();

  OccupancyGeometry g;
  const int depth_count = int(level.size());
  int cut = depth_count - 1;  // deepest level: all leaves, so cutting there changes nothing
  if (box_budget > 0) {
    std::size_t above = 0;
    int best = 0;
    for (int d = 0; d < depth_count; ++d) {
      if (above + cut_count[d] <= box_budget || d == 0) best = d;
      if (above + cut_count[d] > box_budget && d > 0) break;
      above += full_count[d];
    }
    if (best < depth_count - 1) {
      cut = best;
      g.truncated = true;
    }
  }
  g.depth_limit = g.truncated ? cut : OccupancyTree::kMaxLevels;
  g.tree_revision = tree.revision();
  g.node_box.assign(tree.nodes().size(), OccupancyGeometry::kNoBox);
  for (int d = 0; d <= cut; ++d) {
    for (std::uint32_t n : level[d]) {
      const OccupancyClass pc = parent_class(n);
      const OccupancyClass c = d == cut ? frontier_class(tree, n) : tree.node(n).cls;
      if (c == pc) continue;  // Alg. 2, line 9
      g.node_box[n] = std::uint32_t(g.boxes.size());
      g.boxes.push_back(OccupancyBox{tree.clipped_box(n), c, pc, std::uint8_t(d), 0, n});
    }
  }
  return g;
}

namespace {

void collect_leaves(const OccupancyTree& t, std::uint32_t n, int depth_limit, std::vector<OccupancyBox>& out) {
  if (t.outside(n)) return;
  if (t.is_leaf(n) || t.node(n).depth >= depth_limit) {
    out.push_back(OccupancyBox{t.clipped_box(n), frontier_class(t, n), OccupancyClass::Invalid,
                               t.node(n).depth, 0, n});
    return;
  }
  for (int k = 0; k < 8; ++k) collect_leaves(t, t.child(n, k), depth_limit, out);
}

}  // namespace

std::vector<OccupancyBox> leaf_boxes(const OccupancyTree& tree, int depth_limit) {
  std::vector<OccupancyBox> out;
  collect_leaves(tree, tree.root(), depth_limit, out);
  return out;
}

}  // namespace sl
