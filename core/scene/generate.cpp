#include "core/scene/generate.h"

#include "core/scene/neurite_tubes.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "core/util/error.h"
#include "core/util/parallel.h"
#include "core/util/rng.h"

namespace sl {
namespace {

constexpr float kPi = 3.14159265358979f;

// Each tube or blob draws from its own SplitMix64 stream (seed, index), so adding or reordering work
// cannot shift others.
SplitMix64 stream_rng(std::uint64_t seed, std::uint64_t stream) {
  return SplitMix64(splitmix64_mix(splitmix64_mix(seed) ^ (stream * 0xD1B54A32D192ED03ull)));
}

// Work is split into z-slabs of this many slices. Every voxel belongs to one slab and folds its
// contributions in global (tube/blob) order, so the result cannot depend on how TBB schedules slabs.
constexpr int kSlab = 4;

int slab_count(const ivec3& dims) { return (dims.z + kSlab - 1) / kSlab; }

// Voxel index range [lo, hi] whose centres (i + 0.5) lie within [a - r, b + r] on one axis.
void voxel_range(float a, float b, float r, int n, int& lo, int& hi) {
  lo = std::max(0, int(std::ceil(std::min(a, b) - r - 0.5f)));
  hi = std::min(n - 1, int(std::floor(std::max(a, b) + r - 0.5f)));
}

// Each item's index goes to every slab its slices [lo, hi] (from `zrange`, clipped to the volume,
// empty when lo > hi) touch; bins keep item order, which is the per-voxel fold order.
template <class ZRange>
std::vector<std::vector<std::uint32_t>> bin_by_slab(std::size_t count, const ivec3& dims, ZRange zrange) {
  std::vector<std::vector<std::uint32_t>> bins(std::size_t(slab_count(dims)));
  for (std::size_t i = 0; i < count; ++i) {
    int lo, hi;
    zrange(i, lo, hi);
    for (int s = lo / kSlab; lo <= hi && s <= hi / kSlab; ++s) bins[std::size_t(s)].push_back(std::uint32_t(i));
  }
  return bins;
}

// ---- neurites ------------------------------------------------------------------------------------

constexpr float kStep = 1.5f;          // path sampling step (voxels): capsules this long
using neurites::kHalfWidth;  // the profile falls from 1 to 0 over [-0.75, +0.75] around the surface
constexpr float kNeuriteFill = 0.02f;  // estimated non-zero fraction to aim for; overlaps bring it to ~2 %

struct Capsule {  // one piece of a tube: segment a-b, radius varying linearly from ra to rb
  vec3 a, b;
  float ra, rb;
  float brightness;
  std::uint16_t id;
};

struct PathNode {
  vec3 p, d;
  float r;
};

bool outside(const vec3& p, const vec3& box, float margin) {
  return glm::any(glm::lessThan(p, vec3(-margin))) || glm::any(glm::greaterThan(p, box + margin));
}

// Smooth random walk: the direction turns by a bend velocity that itself does a damped random walk,
// giving gently curving paths (curvature radius of tens of voxels) rather than jittery ones.
std::vector<PathNode> walk(SplitMix64& rng, vec3 p, vec3 d, float r0, float length, const vec3& box) {
  const float phase = rng.uniform(0.0f, 2.0f * kPi);
  const float freq = rng.uniform(0.02f, 0.08f);  // radius varies by +-20 % along the tube
  const auto radius = [&](float s) {
    return std::clamp(r0 * (1.0f + 0.2f * std::sin(phase + freq * s)), 1.0f, 4.0f);
  };
  std::vector<PathNode> path{{p, d, radius(0.0f)}};
  vec3 w(0.0f);
  for (float s = kStep; s <= length; s += kStep) {
    w = 0.9f * w + 0.015f * rng.in_ball();
    w -= glm::dot(w, d) * d;  // bend only sideways
    d = glm::normalize(d + w);
    p += kStep * d;
    path.push_back({p, d, radius(s)});
    if (outside(p, box, path.back().r + kHalfWidth + 1.0f)) break;
  }
  return path;
}

// Appends the path as capsules; returns their estimated non-zero voxel volume inside the box.
double add_capsules(const std::vector<PathNode>& path, float brightness, std::uint16_t id, const vec3& box,
                    std::vector<Capsule>& caps) {
  double volume = 0.0;
  for (std::size_t i = 1; i < path.size(); ++i) {
    const Capsule c{path[i - 1].p, path[i].p, path[i - 1].r, path[i].r, brightness, id};
    caps.push_back(c);
    if (!outside(0.5f * (c.a + c.b), box, 0.0f)) {
      const float r = 0.5f * (c.ra + c.rb) + kHalfWidth;
      volume += double(kPi * r * r * glm::distance(c.a, c.b));
    }
  }
  return volume;
}

std::vector<Capsule> neurite_capsules(const ivec3& dims, std::uint32_t seed, std::uint32_t& count) {
  const vec3 box(dims);
  const double voxels = double(dims.x) * double(dims.y) * double(dims.z);
  const float size = float(std::cbrt(voxels));  // typical extent, sets tube lengths
  std::vector<Capsule> caps;
  double filled = 0.0;
  count = 0;
  // One tube (plus branches) per id until the estimated fill is reached; ids must fit in u16.
  while (filled < kNeuriteFill * voxels && count < 65535) {
    const std::uint16_t id = std::uint16_t(++count);
    SplitMix64 rng = stream_rng(seed, id);
    const float brightness = std::round(rng.uniform(120.0f, 255.0f));
    const float u = rng.uniform();
    const float r0 = 1.0f + 3.0f * u * u * u;  // mostly thin, a few thick ones
    vec3 p, d;
    float length;
    if (rng.uniform() < 0.15f) {
      // Crossing tube: enters through a face, heading roughly inwards, and runs until it leaves.
      const int axis = int(rng.uniform() * 3.0f) % 3;
      const bool far = rng.uniform() < 0.5f;
      p = vec3(rng.uniform(), rng.uniform(), rng.uniform()) * box;
      p[axis] = far ? box[axis] : 0.0f;
      vec3 n(0.0f);
      n[axis] = far ? -1.0f : 1.0f;
      d = glm::normalize(n + 0.35f * rng.in_ball());
      length = 4.0f * std::max(box.x, std::max(box.y, box.z));
    } else {
      p = vec3(rng.uniform(), rng.uniform(), rng.uniform()) * box;
      d = rng.unit();
      length = rng.uniform(0.05f, 0.3f) * size;
    }
    const std::vector<PathNode> path = walk(rng, p, d, r0, length, box);
    filled += add_capsules(path, brightness, id, box, caps);
    // Branches share the neurite's id and brightness: one neuron, one segment id.
    const int branches = rng.uniform() < 0.35f ? 1 + int(rng.uniform() < 0.3f) : 0;
    for (int b = 0; b < branches && path.size() >= 8; ++b) {
      const PathNode& at = path[std::size_t(rng.uniform(0.2f, 0.8f) * float(path.size()))];
      const vec3 bd = glm::normalize(at.d + 1.2f * rng.unit());
      const float br = std::max(1.0f, at.r * rng.uniform(0.5f, 0.85f));
      const float bl = rng.uniform(0.3f, 0.6f) * float(path.size()) * kStep;
      filled += add_capsules(walk(rng, at.p, bd, br, bl, box), brightness, id, box, caps);
    }
  }
  return caps;
}

GeneratedVolume neurite_volume(const ivec3& dims, std::uint32_t seed) {
  GeneratedVolume g;
  const std::vector<Capsule> caps = neurite_capsules(dims, seed, g.label_count);
  g.intensity = Volume(VolumeDesc{dims, vec3(1.0f), VoxelType::U8}, "gen");
  g.labels = Volume(VolumeDesc{dims, vec3(1.0f), VoxelType::U16}, "gen");
  std::uint8_t* intensity = g.intensity.as<std::uint8_t>();
  std::uint16_t* labels = g.labels.as<std::uint16_t>();
  const auto bins = bin_by_slab(caps.size(), dims, [&](std::size_t i, int& lo, int& hi) {
    const Capsule& c = caps[i];
    voxel_range(c.a.z, c.b.z, std::max(c.ra, c.rb) + kHalfWidth, dims.z, lo, hi);
  });
  const std::size_t slice = std::size_t(dims.x) * std::size_t(dims.y);

  parallel_for(0, slab_count(dims), [&](int lo, int hi) {
    std::vector<float> best;  // per voxel: signed distance of the deepest tube core so far
    for (int s = lo; s != hi; ++s) {
      const int z0 = s * kSlab, z1 = std::min(dims.z, z0 + kSlab) - 1;
      best.assign(slice * std::size_t(kSlab), std::numeric_limits<float>::infinity());
      for (const std::uint32_t ci : bins[std::size_t(s)]) {
        const Capsule& c = caps[ci];
        const float reach = std::max(c.ra, c.rb) + kHalfWidth;
        ivec3 lo, hi;
        for (int a = 0; a < 3; ++a) voxel_range(c.a[a], c.b[a], reach, dims[a], lo[a], hi[a]);
        lo.z = std::max(lo.z, z0);
        hi.z = std::min(hi.z, z1);
        const vec3 ab = c.b - c.a;
        const float inv_len2 = 1.0f / std::max(glm::dot(ab, ab), 1e-12f);
        for (int z = lo.z; z <= hi.z; ++z) {
          for (int y = lo.y; y <= hi.y; ++y) {
            const std::size_t row = std::size_t(z) * slice + std::size_t(y) * std::size_t(dims.x);
            float* best_row = best.data() + std::size_t(z - z0) * slice + std::size_t(y) * std::size_t(dims.x);
            for (int x = lo.x; x <= hi.x; ++x) {
              neurites::TubeVoxel tv;
              if (!neurites::tube_voxel(c.a, ab, inv_len2, c.ra, c.rb, c.brightness, x, y, z, tv)) continue;
              std::uint8_t& out = intensity[row + std::size_t(x)];
              out = std::uint8_t(std::max(int(out), tv.value));
              if (tv.core && tv.sd < best_row[x]) {
                best_row[x] = tv.sd;
                labels[row + std::size_t(x)] = c.id;
              }
            }
          }
        }
      }
    }
  });
  return g;
}

// ---- blobs ---------------------------------------------------------------------------------------

constexpr float kBlobFill = 0.357f;      // -ln(1 - 0.3): Poisson overlap gives ~30 % coverage
constexpr float kBlobLabelLevel = 0.1f;  // a Gaussian labels the voxels where it alone exceeds this
constexpr float kCut = 3.0f;             // Gaussians end at 3 sigma, shifted so they reach 0 there

struct Blob {
  vec3 c;
  float sigma, amplitude;
};

GeneratedVolume blobs(const ivec3& dims, std::uint32_t seed) {
  const vec3 box(dims);
  const double voxels = double(dims.x) * double(dims.y) * double(dims.z);
  const float size = float(std::cbrt(voxels));
  std::vector<Blob> list;
  double filled = 0.0;
  while (filled < kBlobFill * voxels && list.size() < 65535) {
    SplitMix64 rng = stream_rng(seed, list.size() + 1);
    Blob b;
    b.c = vec3(rng.uniform(), rng.uniform(), rng.uniform()) * box;
    b.sigma = std::max(1.0f, rng.uniform(0.015f, 0.05f) * size);
    b.amplitude = rng.uniform(0.4f, 1.0f);
    const float reach = kCut * b.sigma;
    filled += double(4.0f / 3.0f * kPi * reach * reach * reach);
    list.push_back(b);
  }

  GeneratedVolume g;
  g.label_count = std::uint32_t(list.size());
  g.intensity = Volume(VolumeDesc{dims, vec3(1.0f), VoxelType::U8}, "gen");
  g.labels = Volume(VolumeDesc{dims, vec3(1.0f), VoxelType::U16}, "gen");
  std::uint8_t* intensity = g.intensity.as<std::uint8_t>();
  std::uint16_t* labels = g.labels.as<std::uint16_t>();
  const auto bins = bin_by_slab(list.size(), dims, [&](std::size_t i, int& lo, int& hi) {
    voxel_range(list[i].c.z, list[i].c.z, kCut * list[i].sigma, dims.z, lo, hi);
  });
  const std::size_t slice = std::size_t(dims.x) * std::size_t(dims.y);
  const float floor_value = std::exp(-0.5f * kCut * kCut);

  parallel_for(0, slab_count(dims), [&](int lo, int hi) {
    std::vector<float> sum, top;
    std::vector<std::uint16_t> arg;
    for (int s = lo; s != hi; ++s) {
      const int z0 = s * kSlab, z1 = std::min(dims.z, z0 + kSlab) - 1;
      const std::size_t n = slice * std::size_t(z1 - z0 + 1);
      sum.assign(n, 0.0f);
      top.assign(n, 0.0f);
      arg.assign(n, 0);
      for (const std::uint32_t bi : bins[std::size_t(s)]) {
        const Blob& b = list[bi];
        const float reach = kCut * b.sigma;
        const float k = -0.5f / (b.sigma * b.sigma);
        const float scale = b.amplitude / (1.0f - floor_value);
        ivec3 lo, hi;
        for (int a = 0; a < 3; ++a) voxel_range(b.c[a], b.c[a], reach, dims[a], lo[a], hi[a]);
        lo.z = std::max(lo.z, z0);
        hi.z = std::min(hi.z, z1);
        for (int z = lo.z; z <= hi.z; ++z) {
          for (int y = lo.y; y <= hi.y; ++y) {
            const std::size_t row = std::size_t(z - z0) * slice + std::size_t(y) * std::size_t(dims.x);
            for (int x = lo.x; x <= hi.x; ++x) {
              const vec3 d = vec3(float(x) + 0.5f, float(y) + 0.5f, float(z) + 0.5f) - b.c;
              const float r2 = glm::dot(d, d);
              if (r2 >= reach * reach) continue;
              const float v = scale * (std::exp(k * r2) - floor_value);
              sum[row + std::size_t(x)] += v;
              if (v > top[row + std::size_t(x)]) {
                top[row + std::size_t(x)] = v;
                arg[row + std::size_t(x)] = std::uint16_t(bi + 1);
              }
            }
          }
        }
      }
      const std::size_t base = std::size_t(z0) * slice;
      for (std::size_t i = 0; i < n; ++i) {
        intensity[base + i] = std::uint8_t(std::min(sum[i], 1.0f) * 255.0f + 0.5f);
        labels[base + i] = top[i] > kBlobLabelLevel ? arg[i] : 0;
      }
    }
  });
  return g;
}

// ---- organs --------------------------------------------------------------------------------------

// A few large segments filling most of the volume (shaped like the King Snake data set of the
// SparseLeap paper, Table 1: 4 segments, about 74 % occupancy). The body is a superellipsoid
// |x|^4 + |y|^4 + |z|^4 <= 1 scaled to 0.97 of the box (about 74 % of the voxels); labels: 1 skin
// (the outer 12 % of the body's radius), 2 body (the rest), 3 spine (a tube of radius 0.07 of the
// smallest dimension along a sine curve in x), 4 heart (a sphere of radius 0.12 of the smallest
// dimension, well under 1 % of the voxels). Intensity: a base value per label, modulated by a smooth
// pattern so that transfer functions show structure; 0 outside.
GeneratedVolume organs(const ivec3& dims, std::uint32_t seed) {
  SplitMix64 rng = stream_rng(seed, 1);
  const vec3 box(dims);
  const vec3 centre = 0.5f * box;
  const vec3 half = 0.485f * box;  // 0.97 of the box
  const float small = float(std::min(dims.x, std::min(dims.y, dims.z)));
  const float spine_r = std::max(1.0f, 0.07f * small);
  const float spine_amp = 0.15f * float(dims.y), spine_freq = rng.uniform(1.5f, 2.5f) * 2.0f * kPi / float(dims.x);
  const float spine_phase = rng.uniform(0.0f, 2.0f * kPi);
  const vec3 heart = centre + vec3(rng.uniform(-0.2f, 0.2f), rng.uniform(0.1f, 0.2f), rng.uniform(-0.1f, 0.1f)) * box;
  const float heart_r = std::max(1.0f, 0.12f * small);
  const float skin_level = std::pow(0.88f, 4.0f);
  static constexpr std::uint8_t kBase[5] = {0, 200, 90, 240, 160};

  GeneratedVolume g;
  g.label_count = 4;
  g.intensity = Volume(VolumeDesc{dims, vec3(1.0f), VoxelType::U8}, "gen");
  g.labels = Volume(VolumeDesc{dims, vec3(1.0f), VoxelType::U16}, "gen");
  std::uint8_t* intensity = g.intensity.as<std::uint8_t>();
  std::uint16_t* labels = g.labels.as<std::uint16_t>();
  parallel_for(0, dims.z, [&](int lo, int hi) {
    for (int z = lo; z != hi; ++z) {
      for (int y = 0; y < dims.y; ++y) {
        const std::size_t row = (std::size_t(z) * std::size_t(dims.y) + std::size_t(y)) * std::size_t(dims.x);
        for (int x = 0; x < dims.x; ++x) {
          const vec3 p(float(x) + 0.5f, float(y) + 0.5f, float(z) + 0.5f);
          const vec3 q = (p - centre) / half;
          const vec3 q2 = q * q;
          const float s = q2.x * q2.x + q2.y * q2.y + q2.z * q2.z;
          std::uint16_t id = 0;
          if (s <= 1.0f) {
            id = s > skin_level ? 1 : 2;
            const float sy = centre.y + spine_amp * std::sin(spine_freq * p.x + spine_phase);
            const float dy = p.y - sy, dz = p.z - centre.z;
            if (id == 2 && dy * dy + dz * dz <= spine_r * spine_r) id = 3;
            const vec3 dh = p - heart;
            if (id == 2 && glm::dot(dh, dh) <= heart_r * heart_r) id = 4;
          }
          labels[row + std::size_t(x)] = id;
          if (id == 0) {
            intensity[row + std::size_t(x)] = 0;
          } else {
            const float pattern = 0.5f + 0.5f * std::sin(0.11f * p.x) * std::cos(0.07f * p.y + 0.05f * p.z);
            intensity[row + std::size_t(x)] = std::uint8_t(float(kBase[id]) * (0.8f + 0.2f * pattern) + 0.5f);
          }
        }
      }
    }
  });
  return g;
}

// ---- sphere --------------------------------------------------------------------------------------

GeneratedVolume sphere(const ivec3& dims) {
  GeneratedVolume g;
  g.intensity = Volume(VolumeDesc{dims, vec3(1.0f), VoxelType::F32}, "gen");
  float* out = g.intensity.as<float>();
  const glm::dvec3 centre = glm::dvec3(dims) * 0.5;
  parallel_for(0, dims.z, [&](int lo, int hi) {
    for (int z = lo; z != hi; ++z) {
      for (int y = 0; y < dims.y; ++y) {
        float* row = out + (std::size_t(z) * std::size_t(dims.y) + std::size_t(y)) * std::size_t(dims.x);
        for (int x = 0; x < dims.x; ++x) {
          // Double, so the value is the correctly rounded distance whatever the volume size.
          row[x] = float(glm::length(glm::dvec3(x, y, z) + 0.5 - centre));
        }
      }
    }
  });
  return g;
}

}  // namespace

bool generated_kind_has_labels(const std::string& kind) {
  const bool labelled = kind == "neurites" || kind == "blobs" || kind == "organs";
  if (!labelled && kind != "sphere") {
    throw InputError("gen", "unknown kind '" + kind + "' (expected neurites, blobs, organs or sphere)");
  }
  return labelled;
}

std::uint64_t generated_bytes(const std::string& kind, ivec3 dims) {
  const bool labelled = generated_kind_has_labels(kind);
  const auto bytes = [&](VoxelType t) {
    const VolumeDesc d{dims, vec3(1.0f), t};
    validate_desc(d, "gen", std::numeric_limits<std::uint64_t>::max());
    return d.byte_size();
  };
  return labelled ? bytes(VoxelType::U8) + bytes(VoxelType::U16) : bytes(VoxelType::F32);
}

GeneratedVolume generate_volume(const std::string& kind, ivec3 dims, std::uint32_t seed) {
  const bool labelled = generated_kind_has_labels(kind);
  // Check before any work; labelled kinds need room for the u16 labels too (the larger volume).
  validate_desc(VolumeDesc{dims, vec3(1.0f), labelled ? VoxelType::U16 : VoxelType::F32}, "gen");
  if (kind == "neurites") return neurite_volume(dims, seed);
  if (kind == "blobs") return blobs(dims, seed);
  if (kind == "organs") return organs(dims, seed);
  return sphere(dims);
}

}  // namespace sl
