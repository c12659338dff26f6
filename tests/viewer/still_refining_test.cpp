// The viewer's "still refining" state (apps/viewer/stats_rows.h) on real out-of-core frames: it
// follows the renderer's convergence, so a view that settles short of complete (a pinned level whose
// bricks do not fit the cache, not even a quarter-brick depth pass of them) stops repeating although
// bricks stay missing.
#include <gtest/gtest.h>

#include <memory>

#include "apps/viewer/stats_rows.h"
#include "cache/out_of_core/renderer.h"
#include "core/scene/generate.h"

namespace sl::viewer {
namespace {

TEST(StillRefining, StopsWhenThePinnedViewSettlesIncomplete) {
  GeneratedVolume g = generate_volume("neurites", ivec3(256, 192, 128), 1);
  auto src = std::make_shared<MemoryVolumeSource>(std::make_shared<const Volume>(std::move(g.intensity)), nullptr,
                                                  "neurites");
  const TransferFunction tf = default_transfer_function(0, 255);
  const Camera cam = default_camera(src->desc().extent());
  OutOfCoreSettings os;
  os.cache_mb = 1;  // about 25 of the 192 level-0 bricks: fewer than a depth pass's thinnest shell crosses
  os.lod = 0;
  OutOfCoreRenderer r(src, os, 16);
  RenderSettings s;
  s.width = 128;
  s.height = 96;
  Frame f;
  int refining_frames = 0;
  for (int i = 0; i < 400 && !r.converged(); ++i) {
    f = r.render(OutOfCoreScene{&tf, nullptr, cam}, s);
    refining_frames += still_refining(f.stats) ? 1 : 0;
    EXPECT_EQ(still_refining(f.stats), !r.converged()) << "frame " << i;
    r.wait_for_loads();
  }
  ASSERT_TRUE(r.converged());
  EXPECT_GT(refining_frames, 0) << "the first frames stream bricks in";
  // Bricks stayed missing (in the passes that could not be made complete): the old rule, misses > 0,
  // kept repeating such a view.
  EXPECT_LT(f.stats.cache.completeness, 1.0);
  EXPECT_GE(f.stats.cache.depth_passes, 2) << "depth passes were tried";
  EXPECT_FALSE(still_refining(f.stats));
}

}  // namespace
}  // namespace sl::viewer
