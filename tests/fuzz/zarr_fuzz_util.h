// Shared by the Zarr store fuzzers (zarr_store: v2, zarr3_store: v3): what they do with a store whose
// metadata opened.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "cache/formats/zarr/array.h"
#include "cache/formats/zarr/meta.h"
#include "tests/fuzz/fuzz_util.h"

namespace sl::fuzz {

// Reads the box of the first chunk of every level of `m` (store `store`) through an ArrayReader, as
// a brick read does. Levels whose box would exceed kMaxVolumeBytes are skipped, and nothing is read
// when the reader's fill chunks (one per level) would.
inline void read_first_boxes(const sl::zarr::Multiscale& m, const std::string& store) {
  std::uint64_t fill_bytes = 0;
  for (const auto& l : m.levels) fill_bytes += l.meta.chunk_bytes();
  if (fill_bytes > kMaxVolumeBytes) return;
  const sl::zarr::ArrayReader r(m, store, std::make_shared<sl::zarr::ChunkCache>(kMaxVolumeBytes));
  for (int l = 0; l < r.levels(); ++l) {
    const auto& lv = m.levels[std::size_t(l)];
    const sl::ivec3 n = glm::min(lv.dims, lv.meta.chunk_dims());
    const std::uint64_t bytes = std::uint64_t(n.x) * std::uint64_t(n.y) * std::uint64_t(n.z) *
                                std::uint64_t(sl::voxel_size(lv.meta.type));
    if (bytes > kMaxVolumeBytes) continue;
    std::vector<std::byte> box(bytes);
    r.read_box(l, sl::ivec3(0), n, box.data());
  }
}

}  // namespace sl::fuzz
