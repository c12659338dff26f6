#include "cache/out_of_core/tight_boxes.h"

#include <algorithm>
#include <bit>
#include <climits>
#include <cmath>
#include <span>

namespace sl {

namespace {

// The lowest and highest set bit in bits [from, to] of a bit stream (false: none set).
bool set_bit_range(std::span<const std::uint64_t> bits, std::uint64_t from, std::uint64_t to, std::uint64_t& first,
                   std::uint64_t& last) {
  bool any = false;
  for (std::uint64_t w = from >> 6; w <= to >> 6; ++w) {
    std::uint64_t word = bits[w];
    const std::uint64_t base = w << 6;
    if (base < from) word &= ~std::uint64_t(0) << (from - base);
    if (to - base < 63) word &= ~std::uint64_t(0) >> (63 - (to - base));
    if (word == 0) continue;
    if (!any) first = base + std::uint64_t(std::countr_zero(word));
    last = base + 63 - std::uint64_t(std::countl_zero(word));
    any = true;
  }
  return any;
}

}  // namespace

int TightBoxes::box_level(const Box3& box, const LodParams& lod, const RayGenerator& gen) {
  if (lod.constant() || gen.orthographic) return lod.level_at(0.0f);
  // The nearest and farthest points of the box from the eye, with room for the rays' rounding.
  const float t_near = glm::length(glm::clamp(gen.eye, box.lo, box.hi) - gen.eye);
  const vec3 far_corner = glm::max(glm::abs(box.lo - gen.eye), glm::abs(box.hi - gen.eye));
  const float t_far = glm::length(far_corner);
  const int l0 = lod.level_at(t_near * (1.0f - 1e-4f));
  const int l1 = lod.level_at(t_far * (1.0f + 1e-4f) + 1e-6f);
  return l0 == l1 ? l0 : -1;
}

TightBoxes::Key TightBoxes::key_of(const Box3& box, int level, const BrickLayout& layout) {
  // The box in eighths of level voxels: leaf boxes are whole culling blocks (clipped to the volume).
  const vec3 inv = layout.level_inv_spacing(level) * 8.0f;
  constexpr std::uint64_t kMax = (std::uint64_t(1) << 20) - 1;
  Key k;
  for (int a = 0; a < 3; ++a) {
    const float lo = std::round(box.lo[a] * inv[a]), hi = std::round(box.hi[a] * inv[a]);
    if (!(lo >= 0.0f && hi >= 0.0f && lo <= float(kMax) && hi <= float(kMax))) return Key{};
    k.lo |= std::uint64_t(lo) << (20 * a);
    k.hi |= std::uint64_t(hi) << (20 * a);
  }
  k.lo |= std::uint64_t(level + 1) << 60;  // never 0: Key{} stands for "not rememberable"
  return k;
}

bool TightBoxes::shrink(const Box3& box, int level, const BrickLayout& layout, const BrickCache& cache,
                        const PageTable& page_table, std::uint64_t mask_key, Box3& out) {
  const vec3 inv = layout.level_inv_spacing(level), sp = layout.level_spacing(level);
  const ivec3 dims = layout.dims(level);
  const int b = layout.brick_size;
  const std::int64_t n = layout.stored_size();
  // The trilinear cells (anchor voxels) of the samples within half a voxel of the box, and the
  // bricks holding its voxels: each brick's slot holds the cells anchored at its payload and at the
  // voxel before it (the apron), which covers them all.
  ivec3 c0, c1, b0, b1;
  for (int a = 0; a < 3; ++a) {
    const float ulo = box.lo[a] * inv[a], uhi = box.hi[a] * inv[a];
    c0[a] = std::clamp(int(std::floor(ulo - 1.0f)), 0, dims[a] - 1);
    c1[a] = std::clamp(int(std::floor(uhi)), 0, dims[a] - 1);
    b0[a] = std::clamp(int(std::floor(ulo)), 0, dims[a] - 1) / b;
    b1[a] = c1[a] / b;
  }
  ivec3 lo(INT_MAX), hi(INT_MIN);
  for (int bz = b0.z; bz <= b1.z; ++bz) {
    for (int by = b0.y; by <= b1.y; ++by) {
      for (int bx = b0.x; bx <= b1.x; ++bx) {
        const BrickId id = BrickId::pack(level, ivec3(bx, by, bz));
        const PageEntry e = page_table.get(id);
        if (!e.is_resident()) return false;
        const std::uint32_t slot = e.slot();
        if (!(cache.brick_in(slot) == id) || cache.mask_key(slot) != mask_key) return false;
        const std::span<const std::uint64_t> mask = cache.slot_mask(slot);
        if (mask.empty()) return false;
        const ivec3 first = id.coord() * b - 1;  // the level voxel of stored voxel 0
        const ivec3 a0 = glm::max(c0, first), a1 = glm::min(c1, first + b);
        if (a0.x > a1.x || a0.y > a1.y || a0.z > a1.z) continue;
        for (int z = a0.z; z <= a1.z; ++z) {
          for (int y = a0.y; y <= a1.y; ++y) {
            const std::uint64_t row = std::uint64_t((std::int64_t(z - first.z) * n + (y - first.y)) * n);
            std::uint64_t f = 0, l = 0;
            if (!set_bit_range(mask, row + std::uint64_t(a0.x - first.x), row + std::uint64_t(a1.x - first.x), f, l)) {
              continue;
            }
            lo = glm::min(lo, ivec3(first.x + int(f - row), y, z));
            hi = glm::max(hi, ivec3(first.x + int(l - row), y, z));
          }
        }
      }
    }
  }
  out = box;
  if (lo.x > hi.x) {
    out.hi = out.lo;  // no sample in it is fetched: no ray meets a box without extent
    return true;
  }
  // Cell c holds the samples p with p / spacing in [c + 1/2, c + 3/2) (the first and last cells of
  // the level also those clamped onto them: there the box keeps its face), as in core.
  for (int a = 0; a < 3; ++a) {
    if (lo[a] > 0) out.lo[a] = std::max(box.lo[a], (float(lo[a]) + 0.25f) * sp[a]);
    if (hi[a] < dims[a] - 1) out.hi[a] = std::min(box.hi[a], (float(hi[a]) + 1.75f) * sp[a]);
    if (out.lo[a] > out.hi[a]) {
      out.hi = out.lo;
      return true;
    }
  }
  return true;
}

OccupancyGeometry TightBoxes::tighten(const OccupancyTree& tree, const OccupancyGeometry& g, const BrickLayout& layout,
                                      const BrickCache& cache, const PageTable& page_table, std::uint64_t mask_key,
                                      const LodParams& lod, const RayGenerator& gen) {
  if (mask_key == BrickCache::kNoMask) mask_key = 1;  // as Residency::update_masks keys the slots
  if (mask_key != mask_key_) {
    known_.clear();
    mask_key_ = mask_key;
  }
  shrunk_ = kept_ = 0;
  OccupancyGeometry out = g;
  for (OccupancyBox& ob : out.boxes) {
    if (ob.cls != OccupancyClass::NonEmpty || !effective_leaf(tree, g, ob.node)) continue;
    const int level = box_level(ob.box, lod, gen);
    if (level < 0 || level >= layout.levels) {
      ++kept_;
      continue;
    }
    const Key k = key_of(ob.box, level, layout);
    if (k.lo != 0) {
      const auto it = known_.find(k);
      if (it != known_.end()) {
        ob.box = it->second;
        ++shrunk_;
        continue;
      }
    }
    Box3 t;
    if (!shrink(ob.box, level, layout, cache, page_table, mask_key, t)) {
      ++kept_;
      continue;
    }
    if (k.lo != 0) {
      if (known_.size() >= capacity_) known_.clear();
      known_.emplace(k, t);
    }
    ob.box = t;
    ++shrunk_;
  }
  return out;
}

}  // namespace sl
