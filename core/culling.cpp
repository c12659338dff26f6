#include "core/culling.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

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
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, out.size()), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t i = r.begin(); i != r.end(); ++i) out[i] = classify_block(table.blocks[i], p);
  });
  return out;
}

}  // namespace sl
