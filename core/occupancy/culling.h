// Culling of one block against the transfer function, iso value and enabled labels (paper §5.2,
// DESIGN.md "Occupancy histogram tree"). Reads only the cached BlockMetadata, so a TF or label change re-culls without
// touching volume data.
//
// Sample model that makes EMPTY conservative (a sample in an EMPTY block contributes nothing):
//  - intensity is trilinear, clamped to the edge voxels: every point of the block's closed world box
//    interpolates voxels of the block dilated by one voxel, so its value lies in [min, max];
//  - the label of a sample is that of the voxel containing it (floor of the voxel coordinate,
//    clamped); that voxel lies in the dilated block, so its id is in `labels`;
//  - with labels in use, a sample contributes only if its label is enabled.
// Iso mode: a crossing point p (value == iso) lies in a block whose range contains iso; such a block
// is NON_EMPTY. (The caster must still read the sample just outside a sampled span to bracket it.)
#pragma once

#include <cstdint>
#include <vector>

#include "core/occupancy/block_metadata.h"
#include "core/scene/labels.h"
#include "core/occupancy/occupancy_class.h"
#include "core/scene/render_mode.h"
#include "core/scene/transfer_function.h"

namespace sl {

struct CullParams {
  RenderMode mode = RenderMode::Dvr;
  const TransferFunction* tf = nullptr;  // Dvr/Labels: null = no opacity test
  float iso = 0.0f;
  const LabelSet* enabled = nullptr;     // null = labels not used
};

// EMPTY when an enabled-label set is given (and the block has label metadata) but none of the block's
// labels is enabled; or (Dvr, Labels) tf->max_opacity(min, max) == 0; or (Iso) iso outside [min, max].
// Mip is never empty by value. NON_EMPTY otherwise; UNKNOWN when the metadata is not computed yet.
OccupancyClass classify_block(const BlockMetadata& m, const CullParams& p);

// A key of everything classify_block reads besides the metadata (mode, iso, the transfer function's
// points, the enabled labels): equal keys give equal classes, so derived structures are rebuilt only
// when it changes.
std::uint64_t cull_key(const CullParams& p);

// Every block of the table (parallel), in block_index order. Reuses the metadata: no recomputation.
std::vector<OccupancyClass> classify_blocks(const BlockMetadataTable& table, const CullParams& p);

}  // namespace sl
