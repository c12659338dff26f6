#include "core/culling.h"

#include "core/parallel.h"

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

std::vector<OccupancyClass> classify_blocks(const BlockMetadataTable& table, const CullParams& p) {
  std::vector<OccupancyClass> out(table.blocks.size());
  parallel_for(std::size_t(0), out.size(), [&](std::size_t i) { out[i] = classify_block(table.blocks[i], p); });
  return out;
}

}  // namespace sl
