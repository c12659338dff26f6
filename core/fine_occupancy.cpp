#include "core/fine_occupancy.h"

#include <bit>
#include <string>

#include "core/block_metadata.h"
#include "core/culling.h"
#include "core/error.h"

namespace sl {

void validate_fine_cell(int cell) {
  if (cell != 0 && cell != 4 && cell != 8) {
    throw InputError("--fine-cell", "fine occupancy cell must be 0 (off), 4 or 8 voxels, not " + std::to_string(cell));
  }
}

void FineOccupancy::classify(const BlockMetadataTable& metadata, const CullParams& cull) {
  const BlockGrid& g = metadata.grid;
  // The same test as a culling block's (core/culling.h), so a clear bit is as conservative as EMPTY.
  const std::vector<OccupancyClass> classes = classify_blocks(metadata, cull);
  bits_.assign((classes.size() + 63) / 64, 0u);
  set_ = 0;
  for (std::size_t i = 0; i < classes.size(); ++i) {
    if (classes[i] != OccupancyClass::Empty) bits_[i >> 6] |= std::uint64_t(1) << (i & 63u);
  }
  for (const std::uint64_t w : bits_) set_ += std::size_t(std::popcount(w));
  view_.bits = bits_.data();
  view_.cells = g.blocks;
  view_.cell_size = vec3(float(g.block)) * g.spacing;
  view_.inv_cell_size = 1.0f / view_.cell_size;
}

}  // namespace sl
