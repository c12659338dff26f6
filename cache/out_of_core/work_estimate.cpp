#include "cache/out_of_core/work_estimate.h"

#include <cstddef>
#include <vector>

#include "core/occupancy/block_metadata.h"
#include "core/util/error.h"
#include "core/util/parallel.h"
#include "core/scene/voxel_dispatch.h"

namespace sl {

int work_level(const BrickLayout& layout, int max_cells) {
  for (int l = 0; l < layout.levels; ++l) {
    const ivec3 b = layout.bricks(l);
    if (b.x <= max_cells && b.y <= max_cells && b.z <= max_cells) return l;
  }
  return layout.levels - 1;
}

WorkGrid estimate_work(const VolumeSource& source, const BrickLayout& layout, int level, int block,
                       const CullParams& cull, int part, int parts) {
  const VolumeDesc& d = source.desc();
  WorkGrid g = make_work_grid(d.dims, d.spacing, layout.brick_size << level);
  SL_CHECK(g.cells == layout.bricks(level));
  const bool labels = source.has_labels() && cull.enabled != nullptr;
  const ivec3 S(layout.stored_size());
  const std::size_t n = g.work.size();
  const int per = layout.brick_size / block;
  const ivec3 dims = layout.dims(level);
  parallel_for(std::size_t(0), n, [&](std::size_t lo, std::size_t hi) {
    std::vector<std::byte> iv(std::size_t(layout.stored_voxels()) * std::size_t(voxel_size(d.type)));
    std::vector<std::byte> lv(labels ? std::size_t(layout.stored_voxels()) * std::size_t(voxel_size(source.label_type()))
                                     : 0);
    for (std::size_t i = lo; i < hi; ++i) {
      if (int(i % std::size_t(parts)) != part) continue;
      const ivec3 c(int(i % std::size_t(g.cells.x)), int((i / std::size_t(g.cells.x)) % std::size_t(g.cells.y)),
                    int(i / (std::size_t(g.cells.x) * std::size_t(g.cells.y))));
      const BrickId id = BrickId::pack(level, c);
      try {
        source.read_brick(layout, id, iv, lv);
      } catch (const InputError&) {
        g.work[i] = double(per) * double(per) * double(per);
        continue;
      }
      const VolumeView ivw{iv.data(), S, vec3(1.0f), d.type};
      const VolumeView lvw{labels ? lv.data() : nullptr, S, vec3(1.0f), source.label_type()};
      const ivec3 first_stored = layout.brick_origin(id) - kBrickApron;
      double w = 0.0;
      for (int z = 0; z < per; ++z)
        for (int y = 0; y < per; ++y)
          for (int x = 0; x < per; ++x) {
            const ivec3 b = c * per + ivec3(x, y, z);
            if (b.x * block >= dims.x || b.y * block >= dims.y || b.z * block >= dims.z) continue;  // outside
            const BlockMetadata m =
                compute_block_metadata(ivw, labels ? &lvw : nullptr, first_stored, dims, b * block, block);
            w += classify_block(m, cull) == OccupancyClass::Empty ? 0.0 : 1.0;
          }
      g.work[i] = w;
    }
  });
  return g;
}

}  // namespace sl
