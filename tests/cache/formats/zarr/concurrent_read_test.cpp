// ZarrVolumeSource as the brick loader's worker threads use it (DESIGN.md "Virtual memory"): bricks read by several
// threads at once through one small chunk cache, so that chunks are evicted and decoded again while
// other threads hold them, equal the same bricks read by one thread. scripts/test runs this under
// ThreadSanitizer with the loader, cache and miss-buffer suites (the chunk cache and, on Zarr v3, the
// shard-index cache are shared by the loader's threads).
#include <gtest/gtest.h>

#include <cstddef>
#include <string>
#include <thread>
#include <vector>

#include "cache/brick.h"
#include "cache/formats/ingest.h"
#include "cache/formats/nrrd/nrrd.h"
#include "cache/formats/zarr/source.h"
#include "core/scene/generate.h"
#include "tests/test_util.h"

namespace sl {
namespace {

TEST(ZarrConcurrentReads, ThreadsSharingASmallChunkCacheReadWhatOneThreadReads) {
  const auto dir = test::scratch_dir();
  const GeneratedVolume g = generate_volume("neurites", {40, 36, 34});
  write_nrrd((dir / "v.nrrd").string(), g.intensity);
  write_nrrd((dir / "l.nrrd").string(), g.labels);
  for (const int format : {2, 3}) {
    SCOPED_TRACE(testing::Message() << "Zarr v" << format);
    IngestOptions o;
    o.chunk = 8;
    o.labels = (dir / "l.nrrd").string();
    o.zarr_format = format;
    o.shard = format == 3 ? 2 : 0;
    const std::string store = (dir / (std::to_string(format) + ".zarr")).string();
    ingest((dir / "v.nrrd").string(), store, o);
    // Six 8³ u8 chunks: far fewer than one brick with its apron touches (27), so every brick evicts.
    const ZarrVolumeSource src(store, "", PyramidKind::Mean, 6 * 8 * 8 * 8);
    ASSERT_TRUE(src.has_labels());
    const BrickLayout layout = BrickLayout::make(src.desc(), 8);
    std::vector<BrickId> ids;
    for (int l = 0; l < layout.levels; ++l) {
      const ivec3 n = layout.bricks(l);
      for (int z = 0; z < n.z; ++z)
        for (int y = 0; y < n.y; ++y)
          for (int x = 0; x < n.x; ++x) ids.push_back(BrickId::pack(l, {x, y, z}));
    }
    const std::size_t voxels = layout.stored_voxels();
    const std::size_t label_bytes = voxels * std::size_t(voxel_size(src.label_type()));
    const auto read = [&](BrickId id) {
      std::vector<std::byte> b(voxels + label_bytes);
      src.read_brick(layout, id, std::span(b).first(voxels), std::span(b).subspan(voxels));
      return b;
    };
    std::vector<std::vector<std::byte>> serial;
    for (const BrickId id : ids) serial.push_back(read(id));

    constexpr int kThreads = 4;
    std::vector<std::vector<std::vector<std::byte>>> got(kThreads, std::vector<std::vector<std::byte>>(ids.size()));
    std::vector<std::thread> threads;
    for (int t = 0; t < kThreads; ++t) {
      threads.emplace_back([&, t] {
        // Each thread starts elsewhere in the list, so they collide on chunks in different orders.
        for (std::size_t k = 0; k < ids.size(); ++k) {
          const std::size_t i = (k + std::size_t(t) * ids.size() / kThreads) % ids.size();
          got[std::size_t(t)][i] = read(ids[i]);
        }
      });
    }
    for (auto& th : threads) th.join();
    for (int t = 0; t < kThreads; ++t) {
      for (std::size_t i = 0; i < ids.size(); ++i) {
        ASSERT_EQ(got[std::size_t(t)][i], serial[i]) << "thread " << t << " " << to_string(ids[i]);
      }
    }
    EXPECT_LE(src.chunk_cache().bytes(), src.chunk_cache().max_bytes());
  }
}

}  // namespace
}  // namespace sl
