// The check both Zarr interop suites (v2: zarr/interop_test.cpp, v3: zarr/v3_interop_test.cpp) make of
// a store a peer wrote (and the precomputed suite, precomputed/interop_test.cpp): every brick a
// chunked-store source cuts equals the peer's expected voxels.
#pragma once

#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <memory>
#include <vector>

#include "cache/formats/zarr/source.h"
#include "cache/volume_source.h"
#include "tests/cache/formats/zarr_test_util.h"

namespace sl::test {

// Every stored voxel of every brick of every level equals the expected level voxel (clamped), so
// chunk-crossing bricks and aprons are checked; levels past the stored ones must equal the 2x
// reductions (pyramid.h) of the coarsest stored level.
inline void expect_bricks_match(const VolumeSource& src, const std::filesystem::path& expected, int stored_levels, int brick,
                         bool labels) {
  const BrickLayout layout = BrickLayout::make(src.desc(), brick);
  const VoxelType t = labels ? src.label_type() : src.desc().type;
  const int elem = voxel_size(t);
  // Expected data per level: stored levels from the peer, then MemoryVolumeSource's reductions.
  std::vector<Volume> levels;
  for (int l = 0; l < stored_levels; ++l) {
    VolumeDesc d{layout.dims(l), vec3(1.0f), t};
    Volume v(d);
    const auto b = test::read_bytes(expected.string() + (labels ? ".labels." : ".") + std::to_string(l));
    ASSERT_EQ(b.size(), d.byte_size()) << "level " << l;
    std::memcpy(v.data(), b.data(), b.size());
    levels.push_back(std::move(v));
  }
  auto coarsest = std::make_shared<const Volume>(levels.back());
  std::shared_ptr<MemoryVolumeSource> derived;
  if (labels) {
    VolumeDesc d = coarsest->desc();
    d.type = VoxelType::U8;
    auto dummy = std::make_shared<const Volume>(d);
    derived = std::make_shared<MemoryVolumeSource>(dummy, coarsest);
  } else {
    derived = std::make_shared<MemoryVolumeSource>(coarsest);
  }
  std::vector<std::byte> img(std::size_t(layout.stored_voxels()) * std::size_t(voxel_size(src.desc().type)));
  std::vector<std::byte> lab(labels ? std::size_t(layout.stored_voxels()) * std::size_t(elem) : 0);
  int mismatches = 0;
  for (int l = 0; l < layout.levels; ++l) {
    const Volume& ref = l < stored_levels ? levels[std::size_t(l)]
                                          : (labels ? *derived->label_level(l - stored_levels + 1)
                                                    : derived->level(l - stored_levels + 1));
    ASSERT_EQ(ref.dims(), layout.dims(l)) << "level " << l;
    const ivec3 nb = layout.bricks(l);
    for (int bz = 0; bz < nb.z; ++bz)
      for (int by = 0; by < nb.y; ++by)
        for (int bx = 0; bx < nb.x; ++bx) {
          const BrickId id = BrickId::pack(l, ivec3(bx, by, bz));
          src.read_brick(layout, id, img, lab);
          const std::byte* got = labels ? lab.data() : img.data();
          const int n = layout.stored_size();
          const ivec3 o = layout.brick_origin(id) - 1;
          for (int z = 0; z < n; ++z)
            for (int y = 0; y < n; ++y)
              for (int x = 0; x < n; ++x) {
                const ivec3 v = glm::clamp(o + ivec3(x, y, z), ivec3(0), ref.dims() - 1);
                const std::byte* want = ref.data() + ref.view().index(v.x, v.y, v.z) * std::size_t(elem);
                const std::byte* have = got + std::size_t(layout.stored_index(ivec3(x, y, z))) * std::size_t(elem);
                if (std::memcmp(want, have, std::size_t(elem)) != 0 && ++mismatches <= 5) {
                  ADD_FAILURE() << "level " << l << " brick " << to_string(id) << " voxel " << v.x << "," << v.y << ","
                                << v.z << (labels ? " (labels)" : "");
                }
              }
        }
  }
  EXPECT_EQ(mismatches, 0);
}

}  // namespace sl::test
