#include "core/occupancy/occupancy_geometry.h"

#include <algorithm>
#include <bit>
#include <cmath>

#include "core/occupancy/fine_occupancy.h"
#include "core/util/parallel.h"

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

OccupancyGeometry flatten_sparse_subtrees(const OccupancyTree& tree, const OccupancyGeometry& g) {
  // Measured (neurites, blobs, the MRI, the default data; 512², 2 threads): frames as fast at 4 as with
  // no bound, where 1 (never more boxes) left a third of the gain; the bound keeps a dense subtree with
  // a few EMPTY holes nested rather than a box per leaf.
  constexpr std::uint32_t kMaxLeavesPerBox = 4;
  SL_CHECK(g.tree_revision == tree.revision() && g.node_box.size() == tree.nodes().size());
  const std::size_t slots = tree.nodes().size();
  // Per node: the sampled effective leaves and the boxes of its subtree (the node's own included).
  std::vector<std::uint32_t> leaves(slots, 0u), boxes(slots, 0u);
  auto count = [&](auto&& self, std::uint32_t n) -> void {
    boxes[n] = g.node_box[n] != OccupancyGeometry::kNoBox ? 1u : 0u;
    if (effective_leaf(tree, g, n)) {
      leaves[n] = needs_sampling(effective_class(tree, g, n)) ? 1u : 0u;
      return;
    }
    for (int k = 0; k < 8; ++k) {
      const std::uint32_t c = tree.child(n, k);
      if (tree.outside(c)) continue;
      self(self, c);
      leaves[n] += leaves[c];
      boxes[n] += boxes[c];
    }
  };
  count(count, tree.root());

  OccupancyGeometry out;
  out.depth_limit = g.depth_limit;
  out.truncated = g.truncated;
  out.tree_revision = g.tree_revision;
  out.node_box.assign(slots, OccupancyGeometry::kNoBox);
  auto emit = [&](std::uint32_t n, const OccupancyBox& b) {
    out.node_box[n] = std::uint32_t(out.boxes.size());
    out.boxes.push_back(b);
  };
  // Breadth first; `flat`: inside a subtree replaced by its leaves.
  std::vector<std::pair<std::uint32_t, bool>> level{{tree.root(), false}}, next;
  while (!level.empty()) {
    next.clear();
    for (auto [n, flat] : level) {
      const bool leaf = effective_leaf(tree, g, n);
      if (flat) {
        const OccupancyClass c = effective_class(tree, g, n);
        if (leaf && needs_sampling(c)) {
          emit(n, OccupancyBox{tree.clipped_box(n), c, OccupancyClass::Empty, std::uint8_t(tree.node(n).depth), 0, n});
        }
      } else if (const std::uint32_t i = g.node_box[n]; i != OccupancyGeometry::kNoBox) {
        const OccupancyBox& b = g.boxes[i];
        flat = !leaf && needs_sampling(b.cls) && b.parent_cls == OccupancyClass::Empty && leaves[n] <= kMaxLeavesPerBox * boxes[n];
        if (!flat) emit(n, b);
      }
      if (leaf) continue;
      for (int k = 0; k < 8; ++k) {
        const std::uint32_t c = tree.child(n, k);
        if (!tree.outside(c)) next.emplace_back(c, flat);
      }
    }
    std::swap(level, next);
  }
  return out;
}

namespace {

// The bounds of the set cells of `mask` with cell coordinates in [c0, c1] (inclusive, per axis); false
// when none is set.
bool set_cell_bounds(const VoxelMaskView& mask, const ivec3& c0, const ivec3& c1, ivec3& lo, ivec3& hi) {
  lo = c1;
  hi = c0;
  bool any = false;
  const int w0 = c0.x >> 6, w1 = c1.x >> 6;
  for (int z = c0.z; z <= c1.z; ++z) {
    for (int y = c0.y; y <= c1.y; ++y) {
      const std::uint64_t* row = mask.bits + std::int64_t(z) * mask.plane_words + std::int64_t(y) * mask.row_words;
      for (int w = w0; w <= w1; ++w) {
        std::uint64_t bits = row[w];
        if (w == w0) bits &= ~std::uint64_t(0) << (c0.x & 63);
        if (w == w1 && (c1.x & 63) != 63) bits &= (std::uint64_t(1) << ((c1.x & 63) + 1)) - 1u;
        if (bits == 0u) continue;
        any = true;
        lo.x = std::min(lo.x, 64 * w + std::countr_zero(bits));
        hi.x = std::max(hi.x, 64 * w + 63 - std::countl_zero(bits));
        lo.y = std::min(lo.y, y);
        hi.y = std::max(hi.y, y);
        lo.z = std::min(lo.z, z);
        hi.z = std::max(hi.z, z);
      }
    }
  }
  return any;
}

}  // namespace

OccupancyGeometry tighten_leaf_boxes(const OccupancyTree& tree, const OccupancyGeometry& g, const VoxelMaskView& mask) {
  OccupancyGeometry out = g;
  const ivec3 last = mask.dims - 1;
  parallel_for(std::size_t(0), out.boxes.size(), [&](std::size_t i) {
    OccupancyBox& ob = out.boxes[i];
    if (ob.cls != OccupancyClass::NonEmpty || !effective_leaf(tree, g, ob.node)) return;
    Box3& b = ob.box;
    // The cells a sample inside the box can fall in: cell floor(p / spacing - 1/2) (clamped), one
    // more on each side for rounding.
    ivec3 c0, c1;
    for (int a = 0; a < 3; ++a) {
      const float u0 = b.lo[a] * mask.inv_spacing[a] - 0.5f, u1 = b.hi[a] * mask.inv_spacing[a] - 0.5f;
      c0[a] = std::clamp(int(std::floor(u0)) - 1, 0, last[a]);
      c1[a] = std::clamp(int(std::floor(u1)) + 1, 0, last[a]);
    }
    ivec3 lo, hi;
    if (!set_cell_bounds(mask, c0, c1, lo, hi)) {
      b.hi = b.lo;  // no sample in it is fetched: no ray hits a box without extent
      return;
    }
    // Cell c holds the samples p with p / spacing in [c + 1/2, c + 3/2) (the first and last cells also
    // those clamped onto them: there the box keeps its face).
    // The cells looked at reach a cell beyond the box on each side: the bounds are clipped to the box,
    // and where nothing is left (set cells only outside it) no sample in the box is fetched.
    Box3 t = b;
    for (int a = 0; a < 3; ++a) {
      const float spacing = 1.0f / mask.inv_spacing[a];
      if (lo[a] > 0) t.lo[a] = std::max(b.lo[a], (float(lo[a]) + 0.25f) * spacing);
      if (hi[a] < last[a]) t.hi[a] = std::min(b.hi[a], (float(hi[a]) + 1.75f) * spacing);
      if (t.lo[a] > t.hi[a]) {
        b.hi = b.lo;
        return;
      }
    }
    b = t;
  });
  return out;
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
