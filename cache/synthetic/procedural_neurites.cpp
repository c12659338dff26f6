#include "cache/synthetic/procedural_neurites.h"

#include <algorithm>
#include <atomic>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <list>
#include <mutex>
#include <unordered_map>
#include <vector>

#include "core/scene/neurite_tubes.h"
#include "cache/pyramid.h"
#include "core/util/config.h"
#include "core/util/error.h"
#include "core/util/parallel.h"

namespace sl {
namespace {

using namespace neurites;

constexpr int kExactLevels = 3;      // levels 0 .. 2 are exact
constexpr int kPathLevels = 5;       // levels 3 .. 4 walk the paths; coarser ones use stand-ins
constexpr float kFixed = 256.0f;     // mass fixed-point scale
constexpr std::size_t kCellPathBytes = std::size_t(64) << 20;  // CellPathCache bound

struct Capsule {  // segment a-b, radius varying linearly from ra to rb
  vec3 a, b;
  float ra, rb;
  float brightness;
  std::uint32_t id;
};

// Voxel index range [lo, hi] whose centres (i + 0.5) lie within [min(a, b) - r, max(a, b) + r].
void voxel_range(float a, float b, float r, int& lo, int& hi) {
  lo = int(std::ceil(std::min(a, b) - r - 0.5f));
  hi = int(std::floor(std::max(a, b) + r - 0.5f));
}

Params params_of(const VolumeDesc& d, std::uint32_t seed) { return Params{d.dims, seed}; }

// Cells whose tubes can reach the level-0 box [lo, hi) (their influence ends kMargin outside them).
void cell_range(const Params& p, vec3 lo, vec3 hi, ivec3& c0, ivec3& c1) {
  const ivec3 n = cell_count(p);
  for (int a = 0; a < 3; ++a) {
    c0[a] = std::max(0, int(std::floor((lo[a] - kMargin) / float(kCell))));
    c1[a] = std::min(n[a] - 1, int(std::floor((hi[a] + kMargin) / float(kCell))));
  }
}

// Order-independent label vote: the largest (weight, id), packed so one 64-bit max does it
// (non-negative floats order like their bit patterns).
std::uint64_t pack_vote(float weight, std::uint32_t id) {
  std::uint32_t w;
  std::memcpy(&w, &weight, sizeof(w));
  return (std::uint64_t(w) << 32) | id;
}
void vote(std::uint64_t& slot, std::uint64_t v) {
  std::atomic_ref<std::uint64_t> r(slot);
  std::uint64_t cur = r.load(std::memory_order_relaxed);
  while (v > cur && !r.compare_exchange_weak(cur, v, std::memory_order_relaxed)) {
  }
}

// Accumulates mass and label votes over a region of level voxels; safe from many threads.
struct Accumulator {
  int s;      // level voxel edge in level-0 voxels
  int shift;  // log2(s): points here are inside the volume (>= 0), so a shift is the division
  ivec3 first, n, dims0;
  std::vector<std::uint64_t> mass, votes;
  std::vector<std::uint32_t> peak;  // the max pyramid: the brightest tube centre in each voxel

  Accumulator(int level, ivec3 f, ivec3 count, ivec3 d0)
      : s(1 << level), shift(level), first(f), n(count), dims0(d0),
        mass(std::size_t(count.x) * count.y * count.z, 0), votes(mass.size(), 0), peak(mass.size(), 0) {}

  // Index of the region voxel holding level-0 point q, or -1 (outside the region or the volume).
  std::int64_t index(const vec3& q) const {
    if (q.x < 0.0f || q.y < 0.0f || q.z < 0.0f || q.x >= float(dims0.x) || q.y >= float(dims0.y) ||
        q.z >= float(dims0.z)) {
      return -1;
    }
    const ivec3 v = (ivec3(q) >> shift) - first;  // q >= 0: truncation is floor
    if (v.x < 0 || v.y < 0 || v.z < 0 || v.x >= n.x || v.y >= n.y || v.z >= n.z) return -1;
    return (std::int64_t(v.z) * n.y + v.y) * n.x + v.x;
  }
  // Mass of a tube piece whose centre line lies in voxel i, and its brightness for the max pyramid: a
  // tube's core voxels have its brightness (tube_voxel; radii are >= 1), so the largest level-0 voxel
  // below a coarse voxel is the brightest tube whose centre line passes through it.
  void add(std::int64_t i, float m, float brightness) {
    std::atomic_ref<std::uint64_t>(mass[std::size_t(i)]).fetch_add(std::uint64_t(std::llround(m * kFixed)),
                                                                  std::memory_order_relaxed);
    add_peak(i, brightness);
  }
  // The max pyramid where a tube's radius r is known: every voxel its core (within r of the centre
  // line) reaches at centre-line point q, including voxels the centre line itself never enters.
  void add_peak_around(const vec3& q, float r, float brightness) {
    const vec3 lo = glm::max(q - r, vec3(0.0f)), hi = glm::min(q + r, vec3(dims0) - 1e-3f);
    if (glm::any(glm::greaterThan(lo, hi))) return;
    const ivec3 a = glm::max((ivec3(lo) >> shift) - first, ivec3(0));  // lo, hi >= 0
    const ivec3 b = glm::min((ivec3(hi) >> shift) - first, n - 1);
    for (int z = a.z; z <= b.z; ++z)
      for (int y = a.y; y <= b.y; ++y)
        for (int x = a.x; x <= b.x; ++x) add_peak((std::int64_t(z) * n.y + y) * n.x + x, brightness);
  }
  void add_peak(std::int64_t i, float brightness) {
    const std::uint32_t b = std::uint32_t(std::min(255.0f, std::floor(brightness + 0.5f)));
    std::atomic_ref<std::uint32_t> r(peak[std::size_t(i)]);
    std::uint32_t cur = r.load(std::memory_order_relaxed);
    while (b > cur && !r.compare_exchange_weak(cur, b, std::memory_order_relaxed)) {
    }
  }
  // A path's labelled volume is merged over consecutive samples in one voxel before it votes.
  struct Run {
    std::int64_t voxel = -1;
    float core = 0.0f;
  };
  void add_core(Run& run, std::int64_t i, float core, std::uint32_t id) {
    if (i != run.voxel) flush(run, id);
    run.voxel = i;
    run.core += core;
  }
  void flush(Run& run, std::uint32_t id) {
    if (run.voxel >= 0 && run.core > 0.0f) vote(votes[std::size_t(run.voxel)], pack_vote(run.core, id));
    run = Run{};
  }

  // Mean over the level-0 voxels each region voxel covers inside the volume (odd edges: what exists),
  // or the peak for the max pyramid.
  void finish(PyramidKind pyramid, std::uint8_t* intensity, std::uint32_t* labels) const {
    for (int z = 0; z < n.z; ++z) {
      for (int y = 0; y < n.y; ++y) {
        for (int x = 0; x < n.x; ++x) {
          const ivec3 lo = (first + ivec3(x, y, z)) * s, hi = glm::min(lo + s, dims0);
          const double count = double(hi.x - lo.x) * double(hi.y - lo.y) * double(hi.z - lo.z);
          const std::size_t i = (std::size_t(z) * n.y + y) * n.x + x;
          const double mean = double(mass[i]) / kFixed / count;
          intensity[i] = pyramid == PyramidKind::Max ? std::uint8_t(peak[i])
                                                     : std::uint8_t(std::min(255.0, std::floor(mean + 0.5)));
          if (labels) labels[i] = std::uint32_t(votes[i] & 0xFFFFFFFFu);
        }
      }
    }
  }
};

// ---- Exact: level-0 voxels (as generate_volume's neurites), reduced 2x per level -----------------

void rasterize(const Capsule& c, ivec3 lo, ivec3 hi, ivec3 org, ivec3 ext, std::uint8_t* inten, float* best,
               std::uint32_t* label) {
  const vec3 ab = c.b - c.a;
  const float inv_len2 = 1.0f / std::max(glm::dot(ab, ab), 1e-12f);
  for (int z = lo.z; z <= hi.z; ++z) {
    for (int y = lo.y; y <= hi.y; ++y) {
      const std::size_t row = (std::size_t(z - org.z) * ext.y + std::size_t(y - org.y)) * ext.x;
      for (int x = lo.x; x <= hi.x; ++x) {
        TubeVoxel tv;
        if (!tube_voxel(c.a, ab, inv_len2, c.ra, c.rb, c.brightness, x, y, z, tv)) continue;
        const std::size_t i = row + std::size_t(x - org.x);
        inten[i] = std::uint8_t(std::max(int(inten[i]), tv.value));
        // Deepest core wins; ties go to the larger id so every brick agrees on shared (apron) voxels.
        if (tv.core && (tv.sd < best[i] || (tv.sd == best[i] && c.id > label[i]))) {
          best[i] = tv.sd;
          label[i] = c.id;
        }
      }
    }
  }
}

}  // namespace

// A bounded, thread-safe LRU of cells' walked paths (cell_paths is deterministic, so a cached set is
// the one a walk would give). A cell is walked outside the lock; two threads asking for the same
// missing cell may both walk it, and the first inserted is kept.
class CellPathCache {
 public:
  explicit CellPathCache(std::size_t max_bytes) : max_bytes_(max_bytes) {}

  std::shared_ptr<const neurites::PathSet> get(const neurites::Params& p, ivec3 cell) {
    // Cells per axis are at most 2^24 / neurites::kCell = 2^17: 21 bits each.
    const std::uint64_t key =
        (std::uint64_t(cell.z) << 42) | (std::uint64_t(cell.y) << 21) | std::uint64_t(cell.x);
    {
      std::lock_guard lock(mutex_);
      if (const auto it = index_.find(key); it != index_.end()) {
        lru_.splice(lru_.begin(), lru_, it->second);
        return it->second->paths;
      }
    }
    auto walked = std::make_shared<neurites::PathSet>();
    neurites::cell_paths(p, cell, *walked);
    const std::size_t bytes =
        walked->nodes.size() * sizeof(neurites::PathNode) + walked->paths.size() * sizeof(neurites::PathSet::Path) + sizeof(neurites::PathSet);
    std::lock_guard lock(mutex_);
    if (const auto it = index_.find(key); it != index_.end()) return it->second->paths;
    lru_.push_front(Entry{key, walked, bytes});
    index_.emplace(key, lru_.begin());
    bytes_ += bytes;
    while (bytes_ > max_bytes_ && lru_.size() > 1) {
      bytes_ -= lru_.back().bytes;
      index_.erase(lru_.back().key);
      lru_.pop_back();
    }
    return walked;
  }

 private:
  struct Entry {
    std::uint64_t key;
    std::shared_ptr<const neurites::PathSet> paths;
    std::size_t bytes;
  };
  std::mutex mutex_;
  std::list<Entry> lru_;
  std::unordered_map<std::uint64_t, std::list<Entry>::iterator> index_;
  std::size_t bytes_ = 0, max_bytes_;
};

namespace {

// The capsules (path segments and fibre samples) that can reach the inclusive level-0 box [lo0, hi0].
std::vector<Capsule> capsules_near(const Params& p, CellPathCache& cells, ivec3 lo0, ivec3 hi0) {
  std::vector<Capsule> caps;
  const auto keep = [&](const Capsule& c) {
    const float r = std::max(c.ra, c.rb) + kHalfWidth;
    for (int a = 0; a < 3; ++a) {
      int l, h;
      voxel_range(c.a[a], c.b[a], r, l, h);
      if (h < lo0[a] || l > hi0[a]) return;
    }
    caps.push_back(c);
  };
  ivec3 c0, c1;
  cell_range(p, vec3(lo0), vec3(hi0 + 1), c0, c1);
  for (int cz = c0.z; cz <= c1.z; ++cz)
    for (int cy = c0.y; cy <= c1.y; ++cy)
      for (int cx = c0.x; cx <= c1.x; ++cx) {
        const std::shared_ptr<const PathSet> walked = cells.get(p, ivec3(cx, cy, cz));
        const PathSet& paths = *walked;
        for (const PathSet::Path& path : paths.paths) {
          for (std::uint32_t k = path.begin + 1; k < path.end; ++k) {
            const PathNode &a = paths.nodes[k - 1], &b = paths.nodes[k];
            keep({a.p, b.p, a.r, b.r, path.brightness, path.id});
          }
        }
      }
  std::vector<Fibre> fibres;
  fibres_near(p, vec3(lo0), vec3(hi0 + 1), fibres);
  for (const Fibre& f : fibres) {
    // Samples on the global grid t_k = k * kStep, so every brick builds the same capsules.
    const int k0 = int(std::floor((float(lo0[f.axis]) - kReach) / kStep)) - 1;
    const int k1 = int(std::ceil((float(hi0[f.axis] + 1) + kReach) / kStep)) + 1;
    PathNode prev = fibre_at(f, float(k0) * kStep);
    for (int k = k0 + 1; k <= k1; ++k) {
      const PathNode cur = fibre_at(f, float(k) * kStep);
      keep({prev.p, cur.p, prev.r, cur.r, f.brightness, f.id});
      prev = cur;
    }
  }
  return caps;
}

// Level-0 voxels of one z slab (origin org, extent ext) from the capsules binned to it.
struct Slab {
  std::vector<std::uint8_t> inten;
  std::vector<float> best;
  std::vector<std::uint32_t> label;

  void fill(const std::vector<Capsule>& caps, const std::vector<std::uint32_t>& bin, ivec3 org, ivec3 ext) {
    const std::size_t count = std::size_t(ext.x) * ext.y * ext.z;
    inten.assign(count, 0);
    best.assign(count, std::numeric_limits<float>::infinity());
    label.assign(count, 0);
    for (const std::uint32_t ci : bin) {
      const Capsule& c = caps[ci];
      const float r = std::max(c.ra, c.rb) + kHalfWidth;
      ivec3 lo, hi;
      for (int a = 0; a < 3; ++a) voxel_range(c.a[a], c.b[a], r, lo[a], hi[a]);
      lo = glm::max(lo, org);
      hi = glm::min(hi, org + ext - 1);
      if (glm::any(glm::greaterThan(lo, hi))) continue;
      rasterize(c, lo, hi, org, ext, inten.data(), best.data(), label.data());
    }
  }
};

// Culling bounds of level-l blocks over the level-0 voxels below them (bound_blocks), gathered from
// level-0 voxels as they are synthesised, in any number of parts (the slabs of a read): each part adds
// to the blocks whose dilated box it overlaps. Parts that cover every box give what one scan of each
// box gives (merge_box_metadata).
class LevelZeroBounds {
 public:
  LevelZeroBounds(ivec3 dims0, ivec3 level_dims, int level, int block, std::span<const ivec3> blocks)
      : lo_(blocks.size()), hi_(blocks.size()), out_(blocks.size()) {
    const int s = 1 << level;
    for (std::size_t i = 0; i < blocks.size(); ++i) {
      ivec3 f, e;
      dilated_block(level_dims, blocks[i] * block, block, f, e);
      lo_[i] = f * s;
      hi_[i] = glm::min(e * s, dims0);
    }
  }
  // The union of the boxes (level-0 voxels [first, end)): what must be synthesised.
  void cover(ivec3& first, ivec3& end) const {
    first = ivec3(std::numeric_limits<int>::max());
    end = ivec3(0);
    for (std::size_t i = 0; i < lo_.size(); ++i) first = glm::min(first, lo_[i]), end = glm::max(end, hi_[i]);
  }
  // Level-0 voxels [org, org + ext), x fastest; labels null: bounds without label lists.
  void add(const std::uint8_t* intensity, const std::uint32_t* labels, ivec3 org, ivec3 ext) {
    const VolumeView iv{intensity, ext, vec3(1.0f), VoxelType::U8};
    const VolumeView lv{labels, ext, vec3(1.0f), VoxelType::U32};
    const VolumeView* lp = labels ? &lv : nullptr;
    for (std::size_t i = 0; i < lo_.size(); ++i) {
      const ivec3 a = glm::max(lo_[i], org), b = glm::min(hi_[i], org + ext);
      if (glm::any(glm::greaterThanEqual(a, b))) continue;
      BlockMetadata m = compute_box_metadata(iv, iv, lp, a - org, b - org);
      if (out_[i].computed) {
        merge_box_metadata(out_[i], m);
      } else {
        out_[i] = std::move(m);
      }
    }
  }
  std::vector<BlockMetadata> take() {
    for (const BlockMetadata& m : out_) SL_CHECK(m.computed);  // every box was covered
    return std::move(out_);
  }

 private:
  std::vector<ivec3> lo_, hi_;
  std::vector<BlockMetadata> out_;
};

// The level-l voxels [first, first + n): their level-0 voxels synthesised slab by slab (one level-l
// slice each), every slab reduced 2x per level with pyramid.h — the MemoryVolumeSource definition, so
// identical to its pyramid (mean or max) of the same level-0 data. `bounds` (optional) takes every
// slab's level-0 voxels before they are reduced. out_l null: no labels (nor label lists in `bounds`).
void synthesize_and_reduce(const Params& p, CellPathCache& cells, PyramidKind pyramid, int level, ivec3 first, ivec3 n,
                           std::uint8_t* out_i, std::uint32_t* out_l, LevelZeroBounds* bounds = nullptr) {
  const int s = 1 << level;
  const ivec3 lo0 = first * s, hi0 = glm::min((first + n) * s, p.dims) - 1;  // inclusive level-0 box
  const std::vector<Capsule> caps = capsules_near(p, cells, lo0, hi0);

  // Bin capsules by the level-l slice their level-0 z-range touches.
  std::vector<std::vector<std::uint32_t>> bins(std::size_t(n.z));
  for (std::size_t i = 0; i < caps.size(); ++i) {
    int l, h;
    voxel_range(caps[i].a.z, caps[i].b.z, std::max(caps[i].ra, caps[i].rb) + kHalfWidth, l, h);
    l = std::max(l, lo0.z) / s - first.z;
    h = std::min(h, hi0.z) / s - first.z;
    for (int z = l; z <= h; ++z) bins[std::size_t(z)].push_back(std::uint32_t(i));
  }

  const ivec3 ext0 = hi0 - lo0 + 1;
  Slab slab;
  std::vector<std::byte> ri, rl, ti, tl;  // reduction ping-pong buffers
  for (int zl = 0; zl < n.z; ++zl) {
    const int z0 = (first.z + zl) * s, z1 = std::min(z0 + s, p.dims.z) - 1;
    const ivec3 org(lo0.x, lo0.y, z0), ext(ext0.x, ext0.y, z1 - z0 + 1);
    const std::size_t count = std::size_t(ext.x) * ext.y * ext.z;
    slab.fill(caps, bins[std::size_t(zl)], org, ext);
    if (bounds) bounds->add(slab.inten.data(), out_l ? slab.label.data() : nullptr, org, ext);
    ri.resize(count);
    std::memcpy(ri.data(), slab.inten.data(), count);
    if (out_l) {
      rl.resize(count * 4);
      std::memcpy(rl.data(), slab.label.data(), count * 4);
    }
    ivec3 d = ext;
    for (int r = 0; r < level; ++r) {
      const ivec3 h = (d + 1) / 2;
      ti.resize(std::size_t(h.x) * h.y * h.z);
      tl.resize(ti.size() * 4);
      intensity_reduction(pyramid)(VoxelType::U8, ri.data(), d, ti.data(), 0, h.z);
      if (out_l) reduce_mode(VoxelType::U32, rl.data(), d, tl.data(), 0, h.z);
      std::swap(ri, ti);
      std::swap(rl, tl);
      d = h;
    }
    SL_CHECK(d == ivec3(n.x, n.y, 1));
    const std::size_t slice = std::size_t(n.x) * n.y;
    std::memcpy(out_i + std::size_t(zl) * slice, ri.data(), slice);
    if (out_l) std::memcpy(out_l + std::size_t(zl) * slice, rl.data(), slice * 4);
  }
}

// ---- PathSplat: walked path samples deposited into coarse voxels -----------------------------------

void splat_fibres(const Params& p, Accumulator& acc, vec3 lo0, vec3 hi0, float ds, bool per_sample) {
  std::vector<Fibre> fibres;
  fibres_near(p, lo0, hi0, fibres);
  parallel_for(std::size_t(0), fibres.size(), [&](std::size_t fi) {
    const Fibre& f = fibres[fi];
    const float t_lo = std::max(lo0[f.axis], 0.0f), t_hi = std::min(hi0[f.axis], float(p.dims[f.axis]));
    Accumulator::Run run;
    // Sample centres on the global grid (k + 0.5) * ds: the same samples whichever brick asks.
    for (std::int64_t k = std::int64_t(std::floor(t_lo / ds)); (float(k) + 0.5f) * ds < t_hi; ++k) {
      const float t = (float(k) + 0.5f) * ds;
      const vec3 q = per_sample ? fibre_at(f, t).p : fibre_centre(f, t);
      if (per_sample) acc.add_peak_around(q, fibre_at(f, t).r, f.brightness);
      const std::int64_t i = acc.index(q);
      if (i < 0) {
        acc.flush(run, f.id);
        continue;
      }
      if (per_sample) {  // exact radius and arc length at this sample
        const PathNode at = fibre_at(f, t);
        const float arc = glm::length(at.d) * ds;
        acc.add(i, f.brightness * cross_section(at.r) * arc, f.brightness);
        acc.add_core(run, i, kPi * at.r * at.r * arc, f.id);
      } else {  // coarse: the fibre's mean line density
        acc.add(i, f.line_mass * ds, f.brightness);
        acc.add_core(run, i, f.line_core * ds, f.id);
      }
    }
    acc.flush(run, f.id);
  });
}

void path_splat(const Params& p, PyramidKind pyramid, int level, ivec3 first, ivec3 n, std::uint8_t* out_i, std::uint32_t* out_l) {
  const int s = 1 << level;
  Accumulator acc(level, first, n, p.dims);
  const vec3 lo0(first * s), hi0(glm::min((first + n) * s, p.dims));
  ivec3 c0, c1;
  cell_range(p, lo0, hi0, c0, c1);
  const ivec3 nc = c1 - c0 + 1;
  parallel_for(std::int64_t(0), std::int64_t(nc.x) * nc.y * nc.z, [&](std::int64_t ci) {
    const ivec3 c = c0 + ivec3(int(ci % nc.x), int(ci / nc.x % nc.y), int(ci / (std::int64_t(nc.x) * nc.y)));
    PathSet paths;
    cell_paths(p, c, paths);
    for (const PathSet::Path& path : paths.paths) {
      Accumulator::Run run;
      for (std::uint32_t k = path.begin + 1; k < path.end; ++k) {
        const PathNode &a = paths.nodes[k - 1], &b = paths.nodes[k];
        const vec3 mid = 0.5f * (a.p + b.p);
        const float r = 0.5f * (a.r + b.r), len = glm::distance(a.p, b.p);
        acc.add_peak_around(mid, r, path.brightness);
        const std::int64_t i = acc.index(mid);
        if (i < 0) {
          acc.flush(run, path.id);
          continue;
        }
        acc.add(i, path.brightness * cross_section(r) * len, path.brightness);
        acc.add_core(run, i, kPi * r * r * len, path.id);
      }
      acc.flush(run, path.id);
    }
  });
  splat_fibres(p, acc, lo0, hi0, std::max(kStep, float(s) / 8.0f), true);
  acc.finish(pyramid, out_i, out_l);
}

// ---- LineSplat and CellSum: tubes from their hashes, without walking -------------------------------

void hashed_splat(const Params& p, PyramidKind pyramid, int level, ivec3 first, ivec3 n, std::uint8_t* out_i, std::uint32_t* out_l) {
  const int s = 1 << level;
  Accumulator acc(level, first, n, p.dims);
  const vec3 lo0(first * s), hi0(glm::min((first + n) * s, p.dims));
  const ivec3 nc = cell_count(p);
  if (s < kCell) {
    // Voxels smaller than a cell: each tube's mass spread along its stand-in segment, a quarter
    // voxel apart.
    ivec3 c0, c1;
    cell_range(p, lo0, hi0, c0, c1);
    const ivec3 m = c1 - c0 + 1;
    parallel_for(std::int64_t(0), std::int64_t(m.x) * m.y * m.z, [&](std::int64_t ci) {
      const ivec3 c = c0 + ivec3(int(ci % m.x), int(ci / m.x % m.y), int(ci / (std::int64_t(m.x) * m.y)));
      std::vector<TubeMass> tubes;
      cell_tube_masses(p, c, tubes);
      for (const TubeMass& t : tubes) {
        const int samples = 1 + int(glm::distance(t.a, t.b) * 4.0f / float(s));
        const float w = 1.0f / float(samples);
        Accumulator::Run run;
        for (int j = 0; j < samples; ++j) {
          const std::int64_t i = acc.index(glm::mix(t.a, t.b, (float(j) + 0.5f) * w));
          if (i < 0) {
            acc.flush(run, t.id);
            continue;
          }
          acc.add(i, t.mass * w, t.brightness);
          acc.add_core(run, i, t.core * w, t.id);
        }
        acc.flush(run, t.id);
      }
    });
  } else {
    // Whole cells per voxel (k³ of them). Past 2³ cells a voxel adds up a regular subset of 2³,
    // scaled up: about 128 tubes, enough that the subset's error stays near the u8 rounding of these
    // levels (means of 1-3), and the 8 TiB example's coarsest brick stays cheap.
    const int k = s / kCell, stride = std::max(1, k / 2);
    parallel_for(0, n.z * n.y, [&](int row) {
      const int z = row / n.y, y = row % n.y;
      for (int x = 0; x < n.x; ++x) {
        const ivec3 v = first + ivec3(x, y, z);
        const ivec3 c0 = v * k, cells = glm::min((v + 1) * k, nc) - c0;  // a far-face voxel has fewer
        const ivec3 samples = (cells + stride - 1) / stride;
        const double scale = double(cells.x) * cells.y * cells.z / (double(samples.x) * samples.y * samples.z);
        const auto at = [&](int a, int j) { return c0[a] + std::min(j * stride + stride / 2, cells[a] - 1); };
        double mass = 0.0;
        float peak = 0.0f;
        std::uint64_t best = 0;
        for (int j = 0; j < samples.z; ++j)
          for (int i = 0; i < samples.y; ++i)
            for (int h = 0; h < samples.x; ++h) {
              const CellSummary cs = cell_summary(p, ivec3(at(0, h), at(1, i), at(2, j)));
              mass += double(cs.mass) * scale;
              peak = std::max(peak, cs.peak);
              if (cs.top_id) best = std::max(best, pack_vote(cs.top_core, cs.top_id));
            }
        const std::size_t i = (std::size_t(z) * n.y + y) * n.x + x;
        acc.mass[i] = std::uint64_t(std::llround(mass * kFixed));  // this thread owns row `row`
        acc.votes[i] = best;
        acc.add_peak(std::int64_t(i), peak);
      }
    });
  }
  splat_fibres(p, acc, lo0, hi0, float(s), false);  // one sample per voxel length
  acc.finish(pyramid, out_i, out_l);
}

}  // namespace

ProceduralNeuritesSource::ProceduralNeuritesSource(ivec3 dims, std::uint32_t seed, std::string name,
                                                   PyramidKind pyramid)
    : seed_(seed), name_(std::move(name)), pyramid_(pyramid), cell_paths_(std::make_shared<CellPathCache>(kCellPathBytes)) {
  for (int a = 0; a < 3; ++a) {
    if (dims[a] <= 0) throw InputError(name_, "dimensions must be positive");
  }
  desc_.dims = dims;
  desc_.spacing = vec3(1.0f);
  desc_.type = VoxelType::U8;
}

ProceduralNeuritesSource::Method ProceduralNeuritesSource::method(int level) {
  if (level < kExactLevels) return Method::Exact;
  if (level < kPathLevels) return Method::PathSplat;
  return (1 << level) < kCell ? Method::LineSplat : Method::CellSum;
}

void ProceduralNeuritesSource::synthesize(int level, ivec3 first, ivec3 n, std::uint8_t* intensity,
                                          std::uint32_t* labels) const {
  const Params p = params_of(desc_, seed_);
  switch (method(level)) {
    case Method::Exact: synthesize_and_reduce(p, *cell_paths_, pyramid_, level, first, n, intensity, labels); break;
    case Method::PathSplat: path_splat(p, pyramid_, level, first, n, intensity, labels); break;
    case Method::LineSplat:
    case Method::CellSum: hashed_splat(p, pyramid_, level, first, n, intensity, labels); break;
  }
}

void ProceduralNeuritesSource::read_brick(const BrickLayout& layout, BrickId id, std::span<std::byte> out_intensity,
                                          std::span<std::byte> out_labels) const {
  read(layout, id, out_intensity, out_labels, 0, nullptr);
}

// On the exact levels the bounds come from the level-0 voxels the read synthesises anyway; elsewhere
// as bound_blocks gives them.
void ProceduralNeuritesSource::read_brick_bounded(const BrickLayout& layout, BrickId id,
                                                  std::span<std::byte> out_intensity, std::span<std::byte> out_labels,
                                                  int block, std::vector<BlockMetadata>& bounds) const {
  if (id.level() == 0 || method(id.level()) != Method::Exact) {
    VolumeSource::read_brick_bounded(layout, id, out_intensity, out_labels, block, bounds);
    return;
  }
  read(layout, id, out_intensity, out_labels, block, &bounds);
}

void ProceduralNeuritesSource::read(const BrickLayout& layout, BrickId id, std::span<std::byte> out_intensity,
                                    std::span<std::byte> out_labels, int block,
                                    std::vector<BlockMetadata>* bounds) const {
  check_request(layout, id, out_intensity, out_labels);
  ivec3 first, n;
  brick_read_box(layout, id, first, n);
  const std::size_t count = std::size_t(n.x) * n.y * n.z;
  std::vector<std::uint8_t> inten(count);
  std::vector<std::uint32_t> labels(out_labels.empty() ? 0 : count);
  std::uint32_t* lp = out_labels.empty() ? nullptr : labels.data();
  if (bounds) {
    // The read box (payload and apron) covers every culling block of the payload dilated by one voxel.
    const std::vector<ivec3> blocks = brick_culling_blocks(layout, id, block);
    LevelZeroBounds b(desc_.dims, layout.dims(id.level()), id.level(), block, blocks);
    synthesize_and_reduce(params_of(desc_, seed_), *cell_paths_, pyramid_, id.level(), first, n, inten.data(), lp, &b);
    *bounds = b.take();
  } else {
    synthesize(id.level(), first, n, inten.data(), lp);
  }
  fill_brick(layout, id, reinterpret_cast<const std::byte*>(inten.data()), first, n, 1, out_intensity);
  if (!out_labels.empty()) {
    fill_brick(layout, id, reinterpret_cast<const std::byte*>(labels.data()), first, n, 4, out_labels);
  }
}

bool ProceduralNeuritesSource::bound_blocks(const BrickLayout& layout, int level, int block,
                                            std::span<const ivec3> blocks, std::span<BlockMetadata> out) const {
  SL_CHECK(level >= 1 && level < layout.levels && blocks.size() == out.size());
  if (blocks.empty()) return true;
  if (method(level) != Method::Exact) {
    for (BlockMetadata& m : out) {
      m = BlockMetadata{};
      m.computed = true;
      m.min = 0.0f;
      m.max = 255.0f;
    }
    return true;
  }
  // Each block's dilated box at the level, as level-0 voxels; all of them synthesised at once.
  LevelZeroBounds b(desc_.dims, layout.dims(level), level, block, blocks);
  ivec3 first, end;
  b.cover(first, end);
  const ivec3 n = end - first;
  const std::size_t count = std::size_t(n.x) * n.y * n.z;
  std::vector<std::uint8_t> inten(count);
  std::vector<std::uint32_t> labels(count);
  synthesize(0, first, n, inten.data(), labels.data());
  b.add(inten.data(), labels.data(), first, n);
  std::vector<BlockMetadata> ms = b.take();
  std::move(ms.begin(), ms.end(), out.begin());
  return true;
}

// ---- "procedural:neurites:XxYxZ[:seed]" ------------------------------------------------------------

bool is_procedural_spec(const std::string& spec) { return spec.rfind("procedural:", 0) == 0; }

std::unique_ptr<VolumeSource> parse_volume_spec(const std::string& spec, PyramidKind pyramid) {
  const auto fail = [&](const std::string& why) -> std::unique_ptr<VolumeSource> {
    throw InputError(spec, why + " (expected procedural:neurites:XxYxZ[:seed], e.g. procedural:neurites:32768x32768x8192)");
  };
  const std::string prefix = "procedural:neurites:";
  if (spec.rfind(prefix, 0) != 0) {
    return fail(is_procedural_spec(spec) ? "unknown procedural kind" : "not a procedural volume spec");
  }
  const std::string rest = spec.substr(prefix.size());
  const std::size_t colon = rest.find(':');
  const std::string size = rest.substr(0, colon);
  const auto number = [&](const std::string& text, std::uint64_t max, const char* what) {
    std::uint64_t v = 0;
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
    if (text.empty() || ec != std::errc() || end != text.data() + text.size() || v > max) {
      fail(std::string("bad ") + what + " '" + text + "'");
    }
    return v;
  };
  ivec3 dims;
  std::size_t pos = 0;
  for (int a = 0; a < 3; ++a) {
    const std::size_t x = a < 2 ? size.find('x', pos) : std::string::npos;
    if (a < 2 && x == std::string::npos) return fail("dimensions need three values XxYxZ");
    const std::string part = size.substr(pos, a < 2 ? x - pos : std::string::npos);
    dims[a] = int(number(part, 1u << 24, "dimension"));
    if (dims[a] == 0) return fail("dimensions must be positive");
    pos = x + 1;
  }
  std::uint32_t seed = 1;
  if (colon != std::string::npos) seed = std::uint32_t(number(rest.substr(colon + 1), 0xFFFFFFFFull, "seed"));
  return std::make_unique<ProceduralNeuritesSource>(dims, seed, spec, pyramid);
}

}  // namespace sl
