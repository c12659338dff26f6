// Measures the GL segment-list builder against the CPU tile builder on one random occupancy tree
// (thousands of boxes) at a given image size, and checks that both give the same lists. A benchmark
// program, not a test (STYLE.md #11): it prints timings and asserts nothing about them.
//   sl_gl_segment_list_timing [size=1024] [repeats=3] [fallback]
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "core/occupancy/occupancy_geometry.h"
#include "core/occupancy/occupancy_tree.h"
#include "core/lists/segment_list_builder.h"
#include "core/frame/stats.h"
#include "core/lists/visibility_order.h"
#include "gl/gl_segment_list_builder.h"

int main(int argc, char** argv) {
  using namespace sl;
  const int size = argc > 1 ? std::atoi(argv[1]) : 1024;
  const int repeats = argc > 2 ? std::atoi(argv[2]) : 3;
  GlBuilderOptions options;
  options.list_capacity = kMaxEvents;  // the random trees' lists run longer than a renderer's
  if (argc > 3 && std::strcmp(argv[3], "fallback") == 0) options.path = GlBuilderOptions::Path::Fallback;
  try {
    auto context = GlContext::create_headless();
    std::printf("%s\n", context->info().summary().c_str());
    GlSegmentListBuilder builder(*context, options);
    const BlockGrid grid = make_block_grid(ivec3(125, 97, 83), vec3(1.0f), 4);
    OccupancyTree tree;
    OccupancyGeometry geometry;
    for (std::uint64_t seed = 5; geometry.boxes.size() < 2000; ++seed) {  // a random root may stay unsplit
      tree = make_random_occupancy_tree(grid, seed, RandomTreeParams{5, 0.75, 0.5});
      geometry = build_occupancy_geometry(tree);
    }
    Camera cam;
    cam.eye = vec3(190.0f, 140.0f, 230.0f);
    cam.center = vec3(62.0f, 48.0f, 41.0f);
    cam.fov_deg = 35.0f;
    const RayGenerator gen = make_ray_generator(cam, size, size);
    const auto order = build_visibility_order(tree, geometry, view_point(gen));
    SegmentListBuffer cpu, gl;
    std::printf("%dx%d, %zu boxes, %zu entries, GL list capacity %u, path %s\n", size, size, geometry.boxes.size(),
                order.size(), options.list_capacity, to_string(builder.path()));
    for (int r = 0; r < repeats; ++r) {
      const Timer t;
      const SegmentListStats cs = build_segment_lists(geometry, order, gen, cpu);
      const double cpu_ms = t.ms();
      const GlBuildStats gs = builder.build_segment_lists(geometry, order, gen, gl);
      std::printf("CPU %7.1f ms (%llu events) | GL %7.1f ms: upload %.1f, raster %.1f, resolve %.1f, readback %.1f "
                  "(%d bands, %llu records, %llu redraws, %llu dropped)\n",
                  cpu_ms, (unsigned long long)cs.events, gs.total_ms, gs.upload_ms, gs.raster_ms, gs.resolve_ms,
                  gs.readback_ms, gs.bands, (unsigned long long)gs.records, (unsigned long long)gs.redraws,
                  (unsigned long long)gs.dropped_pixels);
    }
    // A GL list past its capacity is conservative by design (gl_segment_list_builder.h); the CPU's
    // has no capacity, so only the others must be equal.
    std::size_t differing = 0, overflowed = 0;
    for (std::size_t i = 0; i < cpu.counts.size(); ++i) {
      if (gl.overflowed(i)) {
        ++overflowed;
        continue;
      }
      bool same = cpu.counts[i] == gl.counts[i];
      for (std::uint32_t k = 0; same && k < cpu.count(i); ++k) {
        same = std::memcmp(&cpu.list(i)[k], &gl.list(i)[k], sizeof(RayEvent)) == 0;
      }
      differing += same ? 0 : 1;
    }
    std::printf("pixels whose lists differ: %zu (GL lists past their capacity, not compared: %zu)\n", differing,
                overflowed);
    return differing == 0 ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sl_gl_segment_list_timing: %s\n", e.what());
    return 1;
  }
}
