// Deterministic neurite geometry for the procedural source (procedural_neurites.h), defined locally
// so that any brick at any level can be synthesised from its coordinates alone:
//  - Local tubes: space is cut into cells of kCell³ voxels; a cell's tubes (smooth random walks with
//    branches, as in generate_volume's neurites) come from a hash of (seed, cell) and are steered
//    back so that they never reach further than kMargin outside the cell. A region needs only the
//    cells within kMargin of it.
//  - Fibres: long axon-like tubes crossing the whole volume roughly along x, y or z (generate_volume's
//    "crossing tubes"): three families, each tilted off its axis, seeded on a kFibreGrid² lattice in
//    coordinates sheared by the tilt; a fibre wanders at most kFibreWander from its sheared line, so a
//    region needs only nearby lattice cells. A fibre has one label id along its whole length.
// Coordinates are level-0 voxel units; voxel i's centre is at i + 0.5 (DESIGN.md "Ray casting").
#pragma once

#include <cstdint>
#include <cmath>
#include <vector>

#include "core/util/math.h"
#include "core/util/rng.h"

namespace sl::neurites {

inline constexpr int kCell = 128;             // local-tube cell edge (voxels)
inline constexpr float kMargin = 24.0f;       // tubes' influence stays within the cell grown by this
inline constexpr float kStep = 1.5f;          // path sampling step: capsules this long
inline constexpr float kHalfWidth = 0.75f;    // intensity profile falls 1 -> 0 across +-0.75 of the surface
inline constexpr float kMaxRadius = 4.0f;
inline constexpr float kReach = kMaxRadius + kHalfWidth;  // furthest a tube affects from its axis
inline constexpr int kFibreGrid = 128;        // fibre lattice spacing (voxels)
inline constexpr float kFibreWander = 36.0f;  // max transverse excursion from the sheared line
inline constexpr float kPi = 3.14159265358979f;
// Integral of the smoothstep profile over a tube's cross-section: pi r^2 plus a halo term
// 2 pi * 0.1 * kHalfWidth^2 (the profile is antisymmetric about the surface, so only the first
// moment survives). Tube mass per unit length = brightness * cross_section(r).
inline float cross_section(float r) { return kPi * r * r + 0.2f * kPi * kHalfWidth * kHalfWidth; }

// One voxel of a tube piece (segment a-b, radius ra -> rb): the intensity profile both neurite
// generators use (the in-memory `gen` and the procedural source), so their data look alike. `ab` and
// `inv_len2` are the segment and 1 / |ab|^2. Returns false when the voxel centre is out of reach.
struct TubeVoxel {
  float sd = 0.0f;  // signed distance of the voxel centre to the tube surface
  int value = 0;    // u8 intensity
  bool core = false;  // inside the labelled core (profile >= 1/2)
};
inline bool tube_voxel(const vec3& a, const vec3& ab, float inv_len2, float ra, float rb, float brightness, int x,
                       int y, int z, TubeVoxel& out) {
  const vec3 pa = vec3(float(x) + 0.5f, float(y) + 0.5f, float(z) + 0.5f) - a;
  const float t = glm::clamp(glm::dot(pa, ab) * inv_len2, 0.0f, 1.0f);
  const vec3 q = pa - t * ab;
  out.sd = std::sqrt(glm::dot(q, q)) - (ra + t * (rb - ra));
  if (out.sd >= kHalfWidth) return false;
  const float u = glm::min((kHalfWidth - out.sd) * (1.0f / (2.0f * kHalfWidth)), 1.0f);
  const float profile = u * u * (3.0f - 2.0f * u);  // smoothstep: 1/2 on the surface
  out.core = profile >= 0.5f;
  // Outside the core, cap below 128 so "intensity >= 128 implies labelled" holds exactly.
  out.value = glm::min(int(brightness * profile + 0.5f), out.core ? 255 : 127);
  return true;
}

struct Params {
  ivec3 dims{0};
  std::uint32_t seed = 1;
};

// A tube's own stream, keyed by its hash: SplitMix64 seeded with the mixed key.
inline SplitMix64 keyed_rng(std::uint64_t key) { return SplitMix64(splitmix64_mix(key)); }

struct PathNode {
  vec3 p, d;
  float r;
};

// Paths flattened into one node array: path k is nodes[begin, end).
struct PathSet {
  struct Path {
    std::uint32_t begin, end;
    float brightness;
    std::uint32_t id;
  };
  std::vector<PathNode> nodes;
  std::vector<Path> paths;
  void clear() {
    nodes.clear();
    paths.clear();
  }
};

ivec3 cell_count(const Params& p);
// Appends the local tubes (main paths and branches) of `cell`.
void cell_paths(const Params& p, ivec3 cell, PathSet& out);

// What a cell holds, from the per-tube hash alone (no path walking): total mass (intensity summed
// over voxels, overlaps ignored) and the tube with the largest labelled (core) volume. Costs a few
// hashes per tube, so coarse levels covering millions of cells stay cheap.
struct CellSummary {
  float mass = 0.0f;
  float peak = 0.0f;  // the brightest tube's brightness: the largest intensity a voxel of the cell gets
  float top_core = 0.0f;
  std::uint32_t top_id = 0;
};
CellSummary cell_summary(const Params& p, ivec3 cell);

// Per tube of a cell: mass, labelled volume and id as in cell_summary, and the straight segment a-b
// standing in for its path (from its start along its initial direction) — for levels whose voxels
// are smaller than a cell but too many to walk every path.
struct TubeMass {
  vec3 a, b;
  float mass, core;
  float brightness;
  std::uint32_t id;
};
void cell_tube_masses(const Params& p, ivec3 cell, std::vector<TubeMass>& out);

struct Fibre {
  int axis;  // runs along this axis; across it, it wanders around (u0, v0) + tilt * t
  float u0, v0;
  float tilt_u, tilt_v;
  float amp[4], omega[4], phase[4];  // two sinusoids per transverse axis
  float r0, r_phase, r_omega;
  float brightness;
  float line_mass;  // mean mass per unit length along the axis (for coarse levels)
  float line_core;  // mean labelled volume per unit length
  std::uint32_t id;
};
// Fibres whose tubes can reach the level-0 box [lo, hi] (voxel-centre coordinates).
void fibres_near(const Params& p, vec3 lo, vec3 hi, std::vector<Fibre>& out);
// Centre, radius and derivative of the centre along t (in .d, not normalised) of a fibre at axis
// coordinate t; fibre_centre is the centre alone, for coarse levels.
PathNode fibre_at(const Fibre& f, float t);
vec3 fibre_centre(const Fibre& f, float t);

}  // namespace sl::neurites
