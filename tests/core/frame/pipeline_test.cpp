// The frame pipeline shared by the in-core and out-of-core renderers (core/frame/pipeline.h): what is
// rebuilt when (geometry on a tree change; lists on a change of view, tree, method or gap threshold,
// DESIGN.md "Ray segment lists"), the list-builder hook, frame setup and overlays, the one cast-parameter function, and
// the metadata counter in Stats.
#include "core/frame/pipeline.h"

#include <gtest/gtest.h>

#include "core/scene/generate.h"
#include "core/occupancy/block_metadata.h"
#include "core/frame/in_core_renderer.h"
#include "core/occupancy/occupancy_tree.h"

namespace sl {
namespace {

using C = OccupancyClass;

struct Fixture {
  BlockGrid grid = make_block_grid(ivec3(64, 48, 40), vec3(1.0f), 8);
  OccupancyTree tree = make_random_occupancy_tree(grid, 11, RandomTreeParams{3, 0.7, 0.5});
  Camera camera = default_camera(vec3(64, 48, 40));
  RayGenerator gen = make_ray_generator(camera, 40, 30);
};

TEST(FramePipeline, GeometryIsRebuiltOnlyWhenTheTreeChanges) {
  Fixture f;
  FramePipeline p;
  Stats st;
  const OccupancyGeometry* g = &p.geometry(f.tree, st);
  EXPECT_EQ(g->tree_revision, f.tree.revision());
  EXPECT_EQ(st.boxes, g->boxes.size());
  EXPECT_GT(st.boxes, 0u);
  EXPECT_EQ(&p.geometry(f.tree, st), g);
  EXPECT_EQ(p.geometry(f.tree, st).tree_revision, f.tree.revision());
  f.tree.set_leaf_class(f.tree.find_leaf(ivec3(0, 0, 0)), C::NonEmpty);
  f.tree.propagate();
  EXPECT_EQ(p.geometry(f.tree, st).tree_revision, f.tree.revision());
  // A different tree with the same content is still another tree.
  OccupancyTree other = make_random_occupancy_tree(f.grid, 11, RandomTreeParams{3, 0.7, 0.5});
  EXPECT_EQ(p.geometry(other, st).tree_revision, other.revision());
}

TEST(FramePipeline, ListsAreRebuiltOnlyForANewViewTreeMethodOrGapThreshold) {
  Fixture f;
  FramePipeline p;
  int builds = 0;
  p.set_list_builder([&](const OccupancyGeometry& g, std::span<const VisibilityEntry> order, const RayGenerator& gen,
                         SegmentListBuffer& out, float eps) {
    ++builds;
    return build_segment_lists(g, order, gen, out, eps);
  });
  Stats st;
  p.geometry(f.tree, st);
  const SegmentListView v = p.lists(f.tree, SkipMethod::SparseLeap, f.gen, 0.0f, st);
  EXPECT_EQ(builds, 1);
  EXPECT_EQ(v.width, 40);
  EXPECT_EQ(v.event_count, st.events);
  EXPECT_GT(st.events, 0u);
  EXPECT_GE(st.list_bytes, st.events * sizeof(RayEvent) + 2u * 40u * 30u * 4u);
  EXPECT_EQ(st.list_overflows, 0u);
  const std::uint64_t events = st.events;

  Stats again;
  p.geometry(f.tree, again);
  p.lists(f.tree, SkipMethod::SparseLeap, f.gen, 0.0f, again);
  EXPECT_EQ(builds, 1) << "same view, tree, method and threshold: reused";
  EXPECT_EQ(again.events, events);
  EXPECT_EQ(again.time_ms.lists, 0.0);
  EXPECT_EQ(again.time_ms.order, 0.0);

  p.lists(f.tree, SkipMethod::SparseLeap, f.gen, 0.25f, st);
  EXPECT_EQ(builds, 2) << "gap threshold";
  p.lists(f.tree, SkipMethod::SparseLeap, make_ray_generator(f.camera, 40, 31), 0.25f, st);
  EXPECT_EQ(builds, 3) << "image size";
  Camera moved = f.camera;
  moved.eye.x += 1.0f;
  p.lists(f.tree, SkipMethod::SparseLeap, make_ray_generator(moved, 40, 31), 0.25f, st);
  EXPECT_EQ(builds, 4) << "view";
  p.invalidate_lists();
  p.lists(f.tree, SkipMethod::SparseLeap, make_ray_generator(moved, 40, 31), 0.25f, st);
  EXPECT_EQ(builds, 5) << "invalidated";

  // bbox lists take the same key but are not SparseLeap lists: the builder is not asked.
  const SegmentListView b = p.lists(f.tree, SkipMethod::BBox, f.gen, 0.0f, st);
  EXPECT_EQ(b.event_count, st.events);
  EXPECT_EQ(b.event_count % 2u, 0u);  // two events per list
  EXPECT_EQ(builds, 5);
  p.geometry(f.tree, st);
  p.lists(f.tree, SkipMethod::SparseLeap, f.gen, 0.0f, st);
  EXPECT_EQ(builds, 6) << "method";
  EXPECT_EQ(st.events, events);

  f.tree.set_leaf_class(f.tree.find_leaf(ivec3(7, 5, 4)), C::Empty);
  f.tree.propagate();
  p.geometry(f.tree, st);
  p.lists(f.tree, SkipMethod::SparseLeap, f.gen, 0.0f, st);
  EXPECT_EQ(builds, 7) << "tree";
}

TEST(FramePipeline, FrameSetupAndOverlays) {
  Fixture f;
  RenderSettings s;
  s.width = 40;
  s.height = 30;
  s.method = SkipMethod::Octree;
  s.mode = RenderMode::Mip;
  Frame frame = begin_frame(s);
  EXPECT_EQ(frame.image.width, 40);
  EXPECT_EQ(frame.image.rgba.size(), 40u * 30u);
  EXPECT_EQ(frame.stats.width, 40);
  EXPECT_EQ(frame.stats.method, "octree");
  EXPECT_EQ(frame.stats.mode, "mip");

  FramePipeline p;
  Stats st;
  p.geometry(f.tree, st);
  s.boxes_overlay = true;
  auto drawn = [](const Frame& fr) {
    for (const vec4& c : fr.image.rgba) {
      if (c != vec4(0.0f)) return true;
    }
    return false;
  };
  Timer total;
  p.finish_frame(frame, s, nullptr, f.gen, total);
  EXPECT_FALSE(drawn(frame)) << "no tree: no boxes";
  EXPECT_GT(frame.stats.time_ms.total, 0.0);
  f.tree.propagate();  // the tree changed since its geometry was built: the boxes would be stale
  p.finish_frame(frame, s, &f.tree, f.gen, total);
  EXPECT_FALSE(drawn(frame));
  p.geometry(f.tree, st);
  p.finish_frame(frame, s, &f.tree, f.gen, total);
  EXPECT_TRUE(drawn(frame));
}

TEST(FramePipeline, OneCastParameterFunctionInAndOutOfCore) {
  GeneratedVolume g = generate_volume("neurites", ivec3(24, 20, 16), 3);
  const TransferFunction tf = default_transfer_function(0, 255);
  const LabelSet some = parse_enable_spec("1-3", g.label_count);
  RenderSettings s;
  s.step = 0.75f;
  s.iso = 90.0f;
  s.ert = true;
  LabelSet storage;
  const CastParams in_core = make_cast_params(Scene{&g.intensity, &g.labels, &tf, &some, Camera{}}, s, storage);
  EXPECT_FLOAT_EQ(in_core.dt, 0.75f * g.intensity.desc().min_spacing());
  EXPECT_TRUE(in_core.label_mask);
  EXPECT_TRUE(in_core.ert);
  EXPECT_EQ(in_core.iso, 90.0f);
  EXPECT_EQ(in_core.lod.levels, 1);
  // Out of core: the frame's step and level of detail, and the labels of the source.
  LodParams lod;
  lod.levels = 4;
  lod.pinned = 2;
  const CastParams ooc = make_cast_params(s, g.intensity.desc(), tf, &some, false, 3.0f, lod);
  EXPECT_FLOAT_EQ(ooc.dt, 3.0f * g.intensity.desc().min_spacing());
  EXPECT_FLOAT_EQ(ooc.inv_dt, 1.0f / ooc.dt);
  EXPECT_FALSE(ooc.label_mask) << "no label volume";
  EXPECT_EQ(ooc.lod.pinned, 2);
  EXPECT_NE(ooc.tf.table, nullptr);
  // Labels mode without a set shows every label.
  s.mode = RenderMode::Labels;
  const CastParams labels = make_cast_params(Scene{&g.intensity, &g.labels, &tf, nullptr, Camera{}}, s, storage);
  EXPECT_FALSE(labels.label_mask);
  EXPECT_TRUE(labels.labels.enabled(1));
  EXPECT_TRUE(labels.labels.enabled(g.label_count));
}

TEST(FramePipeline, InCoreFramesCountTheirMetadataComputations) {
  GeneratedVolume g = generate_volume("neurites", ivec3(40, 32, 24), 5);
  const TransferFunction a = default_transfer_function(0, 255);
  const TransferFunction b({{0, {0, 0, 0, 0}}, {180, {0, 0, 0, 0}}, {200, {1, 1, 1, 1}}});
  Scene scene{&g.intensity, &g.labels, &a, nullptr, default_camera(g.intensity.desc().extent())};
  RenderSettings s;
  s.width = s.height = 24;
  s.block = 8;
  s.fine_cell = 4;
  InCoreRenderer r;
  const std::uint64_t before = block_metadata_computations();
  const Frame first = r.render(scene, s);
  // The culling blocks and the fine occupancy cells (10 x 8 x 6 of 4³ voxels), each once.
  EXPECT_EQ(first.stats.metadata_computed, 5u * 4u * 3u + 10u * 8u * 6u);
  EXPECT_EQ(first.stats.metadata_blocks, 5u * 4u * 3u);
  EXPECT_EQ(block_metadata_computations() - before, first.stats.metadata_computed);
  scene.tf = &b;
  const Frame second = r.render(scene, s);
  EXPECT_EQ(second.stats.metadata_computed, 0u);
  EXPECT_NE(second.stats.samples, first.stats.samples) << "re-culled";
}

}  // namespace
}  // namespace sl
