// The distributed renderer's work estimate (DESIGN.md "Beyond one machine"): per brick of one coarse
// level, how many of its culling blocks can contribute under the current transfer function, iso value
// and labels — the non-empty blocks the renderer will sample. Read from that level's metadata (a coarse
// block's range covers every finer voxel below it, DESIGN.md "Virtual memory", so a region counted
// empty is empty at every level). The k-d split (core/frame/kd_regions.h) balances it; it is recomputed
// when the culling inputs change (their cull_key).
#pragma once

#include "cache/brick.h"
#include "cache/volume_source.h"
#include "core/occupancy/culling.h"
#include "core/frame/kd_regions.h"

namespace sl {

// The finest level whose brick grid has at most `max_cells` bricks along every axis (the coarsest
// level when none has): few enough bricks to read quickly, enough to balance `max_cells` ranks.
int work_level(const BrickLayout& layout, int max_cells);

// The work grid of `level` (cells = its bricks, cell edge B·2^level level-0 voxels). Only the
// bricks with index ≡ part (mod parts) are read, the others stay 0, so `parts` processes can each
// read a share and sum the grids. A brick the source cannot read (an InputError: a corrupt chunk, a
// failed request) counts as fully occupied, the conservative guess: a data fault is the loader's to
// report when the brick is rendered (as missing), not a reason to stop balancing.
WorkGrid estimate_work(const VolumeSource& source, const BrickLayout& layout, int level, int block,
                       const CullParams& cull, int part = 0, int parts = 1);

}  // namespace sl
