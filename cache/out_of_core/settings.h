// What an out-of-core renderer is made with (renderer.h), shared by the parts that own its concerns
// (residency.h, lazy_occupancy.h, cache_pressure.h, prefetch.h).
#pragma once

#include <cstddef>
#include <cstdint>

#include "cache/brick.h"
#include "cache/brick_loader.h"

namespace sl {

struct OutOfCoreSettings {
  int brick = kDefaultBrickSize;     // payload edge B (the culling block must not exceed it)
  std::size_t cache_mb = 1024;       // brick cache budget
  float lod_bias = 1.0f;             // > 1: coarser levels (fewer bricks), < 1: finer
  int lod = -1;                      // >= 0: pin every sample to this level
  std::uint32_t retire_frames = 60;  // tree nodes unused this long are retired (LRU)
  std::size_t upload_budget = 512;   // bricks made resident per frame at most
  int loader_threads = 0;            // 0: min(4, cores)
  RetryPolicy retry;                 // transient read failures (brick_loader.h)
  // Prefetch (prefetch.h): once a frame has every brick it asked for, load within the upload budget
  // and the cache's spare room the next-finer level around the view's focus and, given the next
  // camera (OutOfCoreScene::next_camera), the bricks that view will want finer. Prefetched bricks
  // never evict a brick the last frame used and are the first to go when a frame needs the room.
  bool prefetch = false;
  // Block metadata kept at most (least recently used dropped, cache/metadata_cache.h); 0: four
  // times the culling blocks of the bricks the cache holds, at least 16,384 blocks.
  std::size_t metadata_blocks = 0;
};

}  // namespace sl
