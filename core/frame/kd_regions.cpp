#include "core/frame/kd_regions.h"

#include <algorithm>
#include <cmath>

#include "core/util/error.h"

namespace sl {

float WorkGrid::plane(int a, int i) const {
  const long long v = std::min<long long>((long long)i * cell, dims[a]);
  return float(v) * spacing[a];
}

WorkGrid make_work_grid(ivec3 dims, vec3 spacing, int cell) {
  SL_CHECK(cell > 0 && dims.x > 0 && dims.y > 0 && dims.z > 0);
  WorkGrid g;
  g.dims = dims;
  g.spacing = spacing;
  g.cell = cell;
  g.cells = (dims + cell - 1) / cell;
  g.work.assign(std::size_t(g.cells.x) * std::size_t(g.cells.y) * std::size_t(g.cells.z), 0.0);
  return g;
}

namespace {

struct Builder {
  const WorkGrid& g;
  KdSplit& out;

  double box_work(ivec3 lo, ivec3 hi) const {
    double w = 0.0;
    for (int z = lo.z; z < hi.z; ++z)
      for (int y = lo.y; y < hi.y; ++y)
        for (int x = lo.x; x < hi.x; ++x) w += g.work[g.index(ivec3(x, y, z))];
    return w;
  }

  void leaf(int rank, ivec3 lo, ivec3 hi) {
    KdRegion& r = out.regions[std::size_t(rank)];
    r.lo = lo;
    r.hi = hi;
    r.work = box_work(lo, hi);
    r.clip.enabled = true;
    if (r.empty()) {
      r.clip.lo = r.clip.hi = vec3(0.0f);  // owns no sample
      r.box = Box3{};
      return;
    }
    for (int a = 0; a < 3; ++a) {
      r.clip.lo[a] = lo[a] == 0 ? -INFINITY : g.plane(a, lo[a]);
      r.clip.hi[a] = hi[a] == g.cells[a] ? INFINITY : g.plane(a, hi[a]);
      r.box.lo[a] = g.plane(a, lo[a]);
      r.box.hi[a] = g.plane(a, hi[a]);
    }
  }

  // Returns the child reference (node index, or -1 - rank for a leaf).
  int build(ivec3 lo, ivec3 hi, int rank0, int n) {
    if (n == 1) {
      leaf(rank0, lo, hi);
      return -1 - rank0;
    }
    const int nl = n / 2, nr = n - nl;
    const ivec3 ext = hi - lo;
    // Every cell boundary s inside the box on every axis; the one minimising the per-rank
    // difference |W_left / nl - W_right / nr| (scaled by nl·nr to stay in sums) wins; ties go to the
    // longer axis (compact regions), then to the boundary nearest the proportional position.
    int axis = 0;
    for (int a = 1; a < 3; ++a) axis = ext[a] > ext[axis] ? a : axis;
    int split = hi[axis];  // a box of one cell (or none): the upper side is empty
    double best = INFINITY, best_dist = INFINITY;
    int best_ext = 0;
    for (int a = 0; a < 3; ++a) {
      if (ext[a] < 2) continue;
      std::vector<double> slab(std::size_t(ext[a]), 0.0);  // work per slab along the axis
      for (int z = lo.z; z < hi.z; ++z)
        for (int y = lo.y; y < hi.y; ++y)
          for (int x = lo.x; x < hi.x; ++x) {
            const ivec3 c(x, y, z);
            slab[std::size_t(c[a] - lo[a])] += g.work[g.index(c)];
          }
      double total = 0.0;
      for (double w : slab) total += w;
      const double ideal = lo[a] + double(ext[a]) * nl / n;
      double left = 0.0;
      for (int s = lo[a] + 1; s < hi[a]; ++s) {
        left += slab[std::size_t(s - 1 - lo[a])];
        const double cost = std::abs(left * nr - (total - left) * nl);
        const double dist = std::abs(s - ideal);
        const bool better = cost < best ||
                            (cost == best && (ext[a] > best_ext || (ext[a] == best_ext && dist < best_dist)));
        if (better) {
          best = cost;
          best_ext = ext[a];
          best_dist = dist;
          axis = a;
          split = s;
        }
      }
    }
    const int node = int(out.nodes.size());
    out.nodes.push_back({});
    out.nodes[std::size_t(node)].axis = axis;
    out.nodes[std::size_t(node)].plane = g.plane(axis, split);
    ivec3 mid_hi = hi, mid_lo = lo;
    mid_hi[axis] = split;
    mid_lo[axis] = split;
    const int l = build(lo, mid_hi, rank0, nl);
    const int r = build(mid_lo, hi, rank0 + nl, nr);
    out.nodes[std::size_t(node)].left = l;
    out.nodes[std::size_t(node)].right = r;
    return node;
  }
};

}  // namespace

KdSplit split_regions(const WorkGrid& grid, int ranks) {
  SL_CHECK(ranks >= 1);
  SL_CHECK(grid.work.size() == std::size_t(grid.cells.x) * std::size_t(grid.cells.y) * std::size_t(grid.cells.z));
  KdSplit s;
  s.regions.resize(std::size_t(ranks));
  Builder{grid, s}.build(ivec3(0), grid.cells, 0, ranks);
  return s;
}

std::vector<int> KdSplit::order(const ViewPoint& view) const {
  std::vector<int> out;
  out.reserve(regions.size());
  if (nodes.empty()) {
    out.push_back(0);
    return out;
  }
  // Iterative depth-first walk, near child first.
  std::vector<int> stack{0};
  while (!stack.empty()) {
    const int ref = stack.back();
    stack.pop_back();
    if (ref < 0) {
      out.push_back(-1 - ref);
      continue;
    }
    const Node& n = nodes[std::size_t(ref)];
    const bool lower_first = view.orthographic ? view.forward[n.axis] > 0.0f : view.eye[n.axis] < n.plane;
    stack.push_back(lower_first ? n.right : n.left);
    stack.push_back(lower_first ? n.left : n.right);
  }
  return out;
}

double KdSplit::max_over_mean_work() const {
  double sum = 0.0, mx = 0.0;
  for (const KdRegion& r : regions) {
    sum += r.work;
    mx = std::max(mx, r.work);
  }
  return sum > 0.0 ? mx * double(regions.size()) / sum : 1.0;
}

}  // namespace sl
