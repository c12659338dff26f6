#include "core/occupancy/culling.h"

#include "core/util/parallel.h"

#include <cstring>

namespace sl {

OccupancyClass classify_block(const BlockMetadata& m, const CullParams& p) {
  if (!m.computed) return OccupancyClass::Unknown;  // delayed culling (paper §5.2)
  // Segmented objects: all contained objects disabled -> empty (paper §5.2).
  if (p.enabled && m.has_labels && !p.enabled->any_enabled(m.labels)) return OccupancyClass::Empty;
  switch (p.mode) {
    case RenderMode::Dvr:
    case RenderMode::Labels:
      // Transfer function: completely transparent over [min, max] -> empty.
      if (p.tf && !(p.tf->max_opacity(m.min, m.max) > 0.0f)) return OccupancyClass::Empty;
      break;
    case RenderMode::Iso:
      if (p.iso < m.min || p.iso > m.max) return OccupancyClass::Empty;
      break;
    case RenderMode::Mip:
      break;  // every sample may be the maximum
  }
  return OccupancyClass::NonEmpty;
}

namespace {
std::uint64_t mix(std::uint64_t h, std::uint64_t v) { return h ^ (v + 0x9e3779b97f4a7c15ull + (h << 6) + (h >> 2)); }
std::uint64_t float_bits(float f) {
  std::uint32_t u;
  std::memcpy(&u, &f, 4);
  return u;
}
}  // namespace

std::uint64_t cull_key(const CullParams& p) {
  std::uint64_t key = mix(mix(std::uint64_t(p.mode), float_bits(p.iso)), std::uint64_t(p.enabled != nullptr));
  key = mix(key, std::uint64_t(p.tf != nullptr));
  if (p.tf) {
    for (const TfPoint& q : p.tf->points()) {
      key = mix(key, float_bits(q.value));
      for (int c = 0; c < 4; ++c) key = mix(key, float_bits(q.rgba[c]));
    }
  }
  if (p.enabled) {
    for (const std::uint32_t w : p.enabled->words()) key = mix(key, w);
  }
  return key;
}

std::vector<OccupancyClass> classify_blocks(const BlockMetadataTable& table, const CullParams& p) {
  std::vector<OccupancyClass> out(table.blocks.size());
  parallel_for(std::size_t(0), out.size(), [&](std::size_t i) { out[i] = classify_block(table.blocks[i], p); });
  return out;
}

}  // namespace sl
