#include "core/scene/neurite_tubes.h"

#include <algorithm>
#include <cmath>

namespace sl::neurites {
namespace {

// Tube density: the number of local tubes per full cell is kTubesMin + (hash % kTubesSpread), tuned
// together with the fibre density so that about 2 % of voxels are non-zero, like generate_volume.
constexpr std::uint32_t kTubesMin = 13;
constexpr std::uint32_t kTubesSpread = 11;
constexpr float kMinLength = 24.0f, kMaxLength = 120.0f;  // main path length (voxels)
constexpr float kRadiusBoost = 1.02f;  // E[(1 + 0.2 sin)^2]: the +-20 % radius wobble's area gain
constexpr float kBranchShrink = 0.675f;  // mean of U(0.5, 0.85), the branch/parent radius ratio

std::uint64_t cell_key(const Params& p, ivec3 c) {
  return splitmix64_mix(std::uint64_t(p.seed) * kSplitMixGamma ^
               (std::uint64_t(c.x) | (std::uint64_t(c.y) << 21) | (std::uint64_t(c.z) << 42)));
}
std::uint64_t tube_hash(std::uint64_t key, std::uint32_t i) { return splitmix64_mix(key + (i + 1) * 0xD1B54A32D192ED03ull); }

// Everything that decides a tube's mass comes from one 64-bit hash, in integer fields and table
// look-ups, so cell_summary can add up millions of cells quickly without walking any path; the
// path's shape is drawn from a separate stream seeded by the same hash.
struct TubeParams {
  float brightness;
  int radius_index;  // r0 = radius_table().r0[radius_index]
  int steps;         // main path: steps + 1 nodes
  int branches;
  int branch_steps[2];
};

struct RadiusTable {
  float r0[256];           // 1 + 3 u^3: mostly thin, a few thick ones
  float core[256];         // mean labelled cross-section of the main path, pi r0^2 * kRadiusBoost
  float branch_core[256];  // the same for a branch of radius max(1, kBranchShrink * r0)
  RadiusTable() {
    for (int i = 0; i < 256; ++i) {
      const float u = (float(i) + 0.5f) / 256.0f;
      r0[i] = 1.0f + 3.0f * u * u * u;
      core[i] = kPi * r0[i] * r0[i] * kRadiusBoost;
      const float br = std::max(1.0f, kBranchShrink * r0[i]);
      branch_core[i] = kPi * br * br * kRadiusBoost;
    }
  }
};
const RadiusTable& radius_table() {
  static const RadiusTable table;
  return table;
}

TubeParams tube_params(std::uint64_t h) {
  const auto field = [&](int shift, int n) { return int((h >> shift) & ((1u << n) - 1)); };
  TubeParams t;
  t.brightness = float(120 + (field(0, 8) * 136 >> 8));  // 120 .. 255
  t.radius_index = field(8, 8);
  t.steps = 16 + field(16, 6);                          // 24 .. 118.5 voxels long
  t.branches = field(24, 8) < 90 ? 1 + int(field(32, 8) < 77) : 0;  // 35 % branch, 30 % of those twice
  for (int b = 0; b < 2; ++b) {  // branch length 0.3 .. 0.6 of the main path
    t.branch_steps[b] = t.steps * (77 + (field(40 + 8 * b, 8) * 77 >> 8)) >> 8;
  }
  return t;
}

std::uint32_t tube_count(const Params& p, ivec3 c, std::uint64_t key, vec3& lo, vec3& hi) {
  lo = vec3(c * kCell);
  hi = glm::min(vec3((c + 1) * kCell), vec3(p.dims));
  const vec3 e = hi - lo;
  const float inside = e.x * e.y * e.z / float(kCell * kCell * kCell);  // partial cells at the far faces
  const float n = float(kTubesMin + std::uint32_t(key % kTubesSpread)) * inside;
  const float jitter = float((key >> 40) & 0xFFFFFF) * 0x1p-24f;  // rounds fractional counts fairly
  return std::uint32_t(n + jitter);
}

// Label ids 1 + (linear cell index * 32 + tube) mod (2^31 - 1): unique below 2^31 / 32 cells (4.2 M
// cells in the 8 TiB example); fibres use ids >= 2^31. (kTubesMin + kTubesSpread <= 32.)
std::uint32_t tube_id_base(const Params& p, ivec3 c) {
  const ivec3 n = cell_count(p);
  const std::uint64_t linear = (std::uint64_t(c.z) * std::uint64_t(n.y) + std::uint64_t(c.y)) * std::uint64_t(n.x) +
                               std::uint64_t(c.x);
  return std::uint32_t((linear * 32u) % 0x7FFFFFFFull);
}
std::uint32_t tube_id(std::uint32_t base, std::uint32_t i) { return 1u + (base + i) % 0x7FFFFFFFu; }

// Smooth random walk as in generate_volume (bend velocity doing a damped random walk), plus steering:
// inside the margin the direction is pulled back towards the cell, harder the deeper it goes, and a
// reflection at the wall is the backstop, so no node gets further than kMargin - kReach outside.
void walk(SplitMix64& rng, vec3 p, vec3 d, float r0, int steps, vec3 lo, vec3 hi, std::vector<PathNode>& out) {
  const float phase = rng.uniform(0.0f, 2.0f * kPi);
  const float freq = rng.uniform(0.02f, 0.08f);
  const auto radius = [&](float s) { return std::clamp(r0 * (1.0f + 0.2f * std::sin(phase + freq * s)), 1.0f, kMaxRadius); };
  const float wall = kMargin - kReach;
  out.push_back({p, d, radius(0.0f)});
  vec3 w(0.0f);
  for (int k = 1; k <= steps; ++k) {
    w = 0.9f * w + 0.015f * rng.in_ball();
    w -= glm::dot(w, d) * d;
    vec3 pull(0.0f);
    for (int a = 0; a < 3; ++a) {
      if (p[a] < lo[a]) pull[a] = (lo[a] - p[a]) / wall;
      if (p[a] > hi[a]) pull[a] = (hi[a] - p[a]) / wall;
    }
    d = glm::normalize(d + w + 0.3f * pull);
    for (int a = 0; a < 3; ++a) {
      const float q = p[a] + kStep * d[a];
      if ((q < lo[a] - wall && d[a] < 0.0f) || (q > hi[a] + wall && d[a] > 0.0f)) d[a] = -d[a];
    }
    p += kStep * d;
    out.push_back({p, d, radius(float(k) * kStep)});
  }
}

}  // namespace

ivec3 cell_count(const Params& p) { return (p.dims + kCell - 1) / kCell; }

void cell_paths(const Params& p, ivec3 c, PathSet& out) {
  const std::uint64_t key = cell_key(p, c);
  vec3 lo, hi;
  const std::uint32_t n = tube_count(p, c, key, lo, hi);
  const std::uint32_t base = tube_id_base(p, c);
  for (std::uint32_t i = 0; i < n; ++i) {
    const std::uint64_t h = tube_hash(key, i);
    const TubeParams t = tube_params(h);
    const std::uint32_t id = tube_id(base, i);
    SplitMix64 rng = keyed_rng(h ^ 0x632BE59BD9B4E019ull);
    const vec3 start = lo + vec3(rng.uniform(), rng.uniform(), rng.uniform()) * (hi - lo);
    const std::uint32_t main_begin = std::uint32_t(out.nodes.size());
    walk(rng, start, rng.unit(), radius_table().r0[t.radius_index], t.steps, lo, hi, out.nodes);
    const std::uint32_t main_end = std::uint32_t(out.nodes.size());
    out.paths.push_back({main_begin, main_end, t.brightness, id});
    // Branches share the neurite's id and brightness: one neuron, one segment id.
    for (int b = 0; b < t.branches; ++b) {
      const std::uint32_t at_index = main_begin + std::uint32_t(rng.uniform(0.2f, 0.8f) * float(main_end - main_begin));
      const PathNode at = out.nodes[at_index];  // copy: walk() appends to the same vector
      const vec3 bd = glm::normalize(at.d + 1.2f * rng.unit());
      const float br = std::max(1.0f, at.r * rng.uniform(0.5f, 0.85f));
      const std::uint32_t begin = std::uint32_t(out.nodes.size());
      walk(rng, at.p, bd, br, t.branch_steps[b], lo, hi, out.nodes);
      out.paths.push_back({begin, std::uint32_t(out.nodes.size()), t.brightness, id});
    }
  }
}

namespace {

// Mass (intensity summed over voxels) and labelled volume of a tube with its branches, from its
// parameters alone: length * mean cross-section, overlaps ignored.
void tube_mass(const TubeParams& t, float& mass, float& core) {
  const RadiusTable& table = radius_table();
  const int branch_steps = (t.branches > 0 ? t.branch_steps[0] : 0) + (t.branches > 1 ? t.branch_steps[1] : 0);
  core = (table.core[t.radius_index] * float(t.steps) + table.branch_core[t.radius_index] * float(branch_steps)) * kStep;
  mass = t.brightness * (core + cross_section(0.0f) * float(t.steps + branch_steps) * kStep);
}

// A tube stands in as the segment from its start along its initial direction, of its length times
// this factor. 0.95 puts the segment's midpoint closest to the walked path's centroid, measured over
// 11k tubes: about 10 voxels off on average (walks are fairly straight: end-to-end / length = 0.86).
constexpr float kWalkStraightness = 0.95f;

}  // namespace

CellSummary cell_summary(const Params& p, ivec3 c) {
  const std::uint64_t key = cell_key(p, c);
  vec3 lo, hi;
  const std::uint32_t n = tube_count(p, c, key, lo, hi);
  CellSummary s;
  std::uint32_t top = 0;
  for (std::uint32_t i = 0; i < n; ++i) {
    float mass, core;
    const TubeParams t = tube_params(tube_hash(key, i));
    tube_mass(t, mass, core);
    s.mass += mass;
    s.peak = std::max(s.peak, t.brightness);
    if (core >= s.top_core) {  // ties go to the later tube, which has the larger id
      s.top_core = core;
      top = i;
    }
  }
  if (n > 0) s.top_id = tube_id(tube_id_base(p, c), top);
  return s;
}

void cell_tube_masses(const Params& p, ivec3 c, std::vector<TubeMass>& out) {
  const std::uint64_t key = cell_key(p, c);
  vec3 lo, hi;
  const std::uint32_t n = tube_count(p, c, key, lo, hi);
  const std::uint32_t base = tube_id_base(p, c);
  const float wall = kMargin - kReach;
  for (std::uint32_t i = 0; i < n; ++i) {
    const std::uint64_t h = tube_hash(key, i);
    const TubeParams t = tube_params(h);
    TubeMass m;
    tube_mass(t, m.mass, m.core);
    m.brightness = t.brightness;
    m.id = tube_id(base, i);
    // The first draws of the path's own stream: its start and initial direction (as cell_paths).
    SplitMix64 rng = keyed_rng(h ^ 0x632BE59BD9B4E019ull);
    const vec3 start = lo + vec3(rng.uniform(), rng.uniform(), rng.uniform()) * (hi - lo);
    const vec3 d = rng.unit();
    m.a = start;
    m.b = glm::clamp(start + d * (kWalkStraightness * float(t.steps) * kStep), lo - wall, hi + wall);
    out.push_back(m);
  }
}

namespace {

// Each axis's fibres form a family sharing one tilt (8-17 degrees off the axis, in a direction from
// the seed), so fibres are not axis-aligned yet stay local: in coordinates sheared by the tilt, a
// fibre stays within kFibreWander of its lattice seed.
vec2 family_tilt(const Params& p, int axis) {
  SplitMix64 rng = keyed_rng(std::uint64_t(p.seed) * kSplitMixGamma + std::uint64_t(axis) + 1);
  const float angle = rng.uniform(0.0f, 2.0f * kPi), m = rng.uniform(0.15f, 0.3f);
  return m * vec2(std::cos(angle), std::sin(angle));
}

}  // namespace

void fibres_near(const Params& p, vec3 lo, vec3 hi, std::vector<Fibre>& out) {
  const float reach = kFibreWander + kReach;
  for (int a = 0; a < 3; ++a) {
    const int u = (a + 1) % 3, v = (a + 2) % 3;
    if (hi[a] < -kReach || lo[a] > float(p.dims[a]) + kReach) continue;
    const vec2 tilt = family_tilt(p, a);
    // Seeds whose sheared line can come within reach of the box over its range along the axis.
    const float ta = lo[a] - kReach, tb = hi[a] + kReach;
    const vec2 s0 = tilt * ta, s1 = tilt * tb;
    const float u_lo = lo[u] - std::max(s0.x, s1.x) - reach, u_hi = hi[u] - std::min(s0.x, s1.x) + reach;
    const float v_lo = lo[v] - std::max(s0.y, s1.y) - reach, v_hi = hi[v] - std::min(s0.y, s1.y) + reach;
    const int i0 = int(std::floor(u_lo / kFibreGrid)), i1 = int(std::floor(u_hi / kFibreGrid));
    const int j0 = int(std::floor(v_lo / kFibreGrid)), j1 = int(std::floor(v_hi / kFibreGrid));
    const std::uint64_t family = splitmix64_mix(std::uint64_t(p.seed) * 0xC2B2AE3D27D4EB4Full + std::uint64_t(a) + 1);
    for (int j = j0; j <= j1; ++j) {
      for (int i = i0; i <= i1; ++i) {
        const std::uint64_t key = splitmix64_mix(family ^ ((std::uint64_t(std::uint32_t(i)) << 32) | std::uint32_t(j)));
        const std::uint64_t pick = key % 10;
        const int count = pick < 3 ? 0 : pick < 8 ? 1 : 2;  // 0.9 fibres per lattice cell and axis
        for (int k = 0; k < count; ++k) {
          SplitMix64 rng = keyed_rng(key + std::uint64_t(k + 1) * kSplitMixGamma);
          Fibre f;
          f.axis = a;
          f.u0 = (float(i) + rng.uniform()) * kFibreGrid;
          f.v0 = (float(j) + rng.uniform()) * kFibreGrid;
          f.tilt_u = tilt.x;
          f.tilt_v = tilt.y;
          // Two sinusoids per transverse axis: long gentle bends and shorter wiggles, at most
          // 24 + 10 < kFibreWander voxels off the sheared line.
          const float amp_max[2] = {24.0f, 10.0f}, len_lo[2] = {300.0f, 80.0f}, len_hi[2] = {1200.0f, 250.0f};
          float slope2 = tilt.x * tilt.x + tilt.y * tilt.y;
          for (int s = 0; s < 4; ++s) {
            f.amp[s] = rng.uniform(0.0f, amp_max[s % 2]);
            f.omega[s] = 2.0f * kPi / rng.uniform(len_lo[s % 2], len_hi[s % 2]);
            f.phase[s] = rng.uniform(0.0f, 2.0f * kPi);
            slope2 += 0.5f * f.amp[s] * f.omega[s] * f.amp[s] * f.omega[s];
          }
          const float r = rng.uniform();
          f.r0 = 1.0f + 3.0f * r * r * r;
          f.r_phase = rng.uniform(0.0f, 2.0f * kPi);
          f.r_omega = rng.uniform(0.02f, 0.08f);
          f.brightness = std::round(rng.uniform(120.0f, 255.0f));
          const float arc = std::sqrt(1.0f + slope2);  // mean arc length per unit of axis
          f.line_core = kPi * f.r0 * f.r0 * kRadiusBoost * arc;
          f.line_mass = f.brightness * (f.line_core + cross_section(0.0f) * arc);
          f.id = 0x80000000u | std::uint32_t(rng.next() & 0x7FFFFFFFu);
          if (f.u0 < u_lo || f.u0 > u_hi || f.v0 < v_lo || f.v0 > v_hi) continue;
          out.push_back(f);
        }
      }
    }
  }
}

vec3 fibre_centre(const Fibre& f, float t) {
  const int u = (f.axis + 1) % 3, v = (f.axis + 2) % 3;
  vec3 p;
  p[f.axis] = t;
  p[u] = f.u0 + f.tilt_u * t + f.amp[0] * std::sin(f.omega[0] * t + f.phase[0]) +
         f.amp[1] * std::sin(f.omega[1] * t + f.phase[1]);
  p[v] = f.v0 + f.tilt_v * t + f.amp[2] * std::sin(f.omega[2] * t + f.phase[2]) +
         f.amp[3] * std::sin(f.omega[3] * t + f.phase[3]);
  return p;
}

PathNode fibre_at(const Fibre& f, float t) {
  const int u = (f.axis + 1) % 3, v = (f.axis + 2) % 3;
  PathNode n;
  n.p = fibre_centre(f, t);
  n.d = vec3(0.0f);
  n.d[f.axis] = 1.0f;
  n.d[u] = f.tilt_u + f.amp[0] * f.omega[0] * std::cos(f.omega[0] * t + f.phase[0]) +
           f.amp[1] * f.omega[1] * std::cos(f.omega[1] * t + f.phase[1]);
  n.d[v] = f.tilt_v + f.amp[2] * f.omega[2] * std::cos(f.omega[2] * t + f.phase[2]) +
           f.amp[3] * f.omega[3] * std::cos(f.omega[3] * t + f.phase[3]);
  n.r = std::clamp(f.r0 * (1.0f + 0.2f * std::sin(f.r_phase + f.r_omega * t)), 1.0f, kMaxRadius);
  return n;
}

}  // namespace sl::neurites
