// The CPU's eight-sample DVR batch (core/cast/sample_batch.h): lane for lane the scalar sample and opacity,
// and every ray marched with it equal, bit for bit, to the scalar march (colour, alpha, depth, counts,
// termination), with and without fine cells and the voxel mask (found by the cell walk and by the
// scan), u8 and u16, over random volumes whose small dims put many samples at the faces and in the
// volume's last bytes (the scalar fallback); the batch reading the dense rows and reading the bricked
// copy (core/cast/bricked_volume.h); a ray's spans scanned together (cast_pixel's walk) as the scalar march
// takes them one by one.
#include "core/cast/sample_batch.h"

#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include <algorithm>
#include <cstring>
#include <vector>

#include "core/occupancy/block_metadata.h"
#include "core/cast/bricked_volume.h"
#include "core/occupancy/culling.h"
#include "core/occupancy/fine_occupancy.h"
#include "core/cast/raycast.h"
#include "tests/core/random_scene.h"

namespace sl {
namespace {

using test_scene::RandomScene;
using test_scene::Rng;
using test_scene::SceneShape;

template <class T>
RayCaster<DenseSampler<T, std::uint16_t>> make_caster(const RandomScene& sc, float step, Rng& r) {
  RayCaster<DenseSampler<T, std::uint16_t>> c;
  c.p.mode = RenderMode::Dvr;
  c.p.dt = step * sc.desc.min_spacing();
  c.p.inv_dt = 1.0f / c.p.dt;
  c.p.spacing = sc.desc.spacing;
  c.p.tf = sc.tf.view(step);
  c.p.label_mask = sc.use_labels;
  c.p.labels = sc.enabled.view();
  c.p.ert = r.next() % 2 == 0;
  c.volume.volume = DenseGrid<T>{sc.vol.as<T>(), sc.desc.dims, 1.0f / sc.desc.spacing};
  c.volume.labels = DenseGrid<std::uint16_t>{sc.lab.as<std::uint16_t>(), sc.desc.dims, 1.0f / sc.desc.spacing};
  return c;
}

bool same(const RayAccum& a, const RayAccum& b) {
  return std::memcmp(&a.color, &b.color, sizeof(vec3)) == 0 && std::memcmp(&a.alpha, &b.alpha, sizeof(float)) == 0 &&
         std::memcmp(&a.hit_t, &b.hit_t, sizeof(float)) == 0 && a.samples == b.samples &&
         a.useful_samples == b.useful_samples && a.done == b.done;
}

template <class T>
void check_rays(std::uint64_t seed) {
  if (!sample_batch_available()) return;  // the scalar path is the only one: nothing to compare
  Rng r{seed};
  const RandomScene sc(r, SceneShape{sizeof(T) == 1 ? VoxelType::U8 : VoxelType::U16, 2, 5.0f});
  const float step = r.uni(0.1f, 1.5f);
  auto scalar = make_caster<T>(sc, step, r);
  scalar.p.simd = false;
  auto batched = scalar;
  batched.p.simd = true;
  // The same batch reading the volume's bricks instead of its rows.
  const BrickedVolume bricks(sc.vol.data(), sc.desc.dims, int(sizeof(T)));
  auto bricked = batched;
  bricked.volume.bricks = &bricks;

  // Fine cells and the voxel mask of this transfer function and label set.
  const VolumeView lv = sc.lab.view();
  const int cell = r.next() % 2 ? 4 : 8;
  const BlockMetadataTable cells =
      compute_all_block_metadata(make_block_grid(sc.desc.dims, sc.desc.spacing, cell), sc.vol.view(), &lv);
  CullParams cull;
  cull.mode = RenderMode::Dvr;
  cull.tf = &sc.tf;
  cull.enabled = sc.use_labels ? &sc.enabled : nullptr;
  FineOccupancy fine;
  fine.classify(cells, cull);
  const FineOccupancyView fv = fine.view();
  FineOccupancyView fm = fv;
  VoxelMask mask;
  mask.build(sc.vol.view(), &lv, cull);
  fm.voxels = mask.view();
  // The batch finds the mask's set bits by the cell walk at a dense fill, by the scan at a sparse one.
  FineOccupancyView walked = fm, scanned = fm;
  walked.voxels.fill = 1.0f;
  scanned.voxels.fill = 0.0f;

  const vec3 ext = sc.desc.extent();
  const Box3 vbox{vec3(0.0f), ext};
  for (int i = 0; i < 20; ++i) {
    Ray ray;
    ray.origin = vec3(r.uni(-0.5f, 1.5f), r.uni(-0.5f, 1.5f), r.uni(-0.5f, 1.5f)) * ext;
    // Targets up to the far faces: samples in the volume's last voxels take the fallback.
    const vec3 target = vec3(r.uni(0.0f, 1.0f), r.uni(0.0f, 1.0f), r.uni(0.0f, 1.0f)) * ext;
    vec3 dir = target - ray.origin;
    if (r.next() % 5 == 0) dir[int(r.next() % 3)] = 0.0f;
    if (!(glm::length(dir) > 1e-3f)) continue;
    ray.dir = glm::normalize(dir);
    const Interval iv = intersect(ray, vbox);
    const float t0 = iv.t0 > 0.0f ? iv.t0 : 0.0f;
    if (!(iv.t1 > t0)) continue;
    const int k_end = sample_index(iv.t1, t0, scalar.p.inv_dt);
    const int k0 = int(r.next() % std::uint64_t(k_end + 1));
    const int k1 = k0 + int(r.next() % std::uint64_t(k_end - k0 + 1));
    const FineOccupancyView* const views[] = {nullptr, &fv, &walked, &scanned};
    for (const FineOccupancyView* f : views) {
      // The batch's inputs worked out per span, and taken from the per-frame plans the tile loop makes.
      const BatchPlans<DenseSampler<T, std::uint16_t>> plans(batched, f), bricked_plans(bricked, f);
      RayAccum a, b, c, d;
      scalar.march(ray, t0, k0, k1, a, false, f);
      batched.march(ray, t0, k0, k1, b, false, f);
      batched.march(ray, t0, k0, k1, c, false, f, &plans);
      bricked.march(ray, t0, k0, k1, d, false, f, &bricked_plans);
      RC_ASSERT(same(a, b));
      RC_ASSERT(same(a, c));
      RC_ASSERT(same(a, d));
      // A second span continues the ray as a segment list's next one does.
      scalar.march(ray, t0, k1, k_end, a, false, f);
      batched.march(ray, t0, k1, k_end, b, false, f);
      batched.march(ray, t0, k1, k_end, c, false, f, &plans);
      bricked.march(ray, t0, k1, k_end, d, false, f, &bricked_plans);
      RC_ASSERT(same(a, b));
      RC_ASSERT(same(a, c));
      RC_ASSERT(same(a, d));
    }
    // A segment list's sampled spans (random cuts of the ray, some skipped) handed to the scan together,
    // in chunks of random sizes (cast_pixel's scanned walk): the scalar march span by span.
    std::vector<SampleSpan> spans;
    for (int k = 0; k < k_end;) {
      const int len = 1 + int(r.next() % 24u);
      if (r.next() % 3 != 0) spans.push_back(SampleSpan{k, std::min(k + len, k_end)});
      k += len;
    }
    const BatchPlans<DenseSampler<T, std::uint16_t>> plans(batched, &scanned);
    BatchMarch<DenseSampler<T, std::uint16_t>> batch(batched);
    RC_ASSERT(batch.prepare(ray, t0, &scanned, &plans));
    RC_ASSERT(batch.scan);
    RayAccum a, b;
    for (const SampleSpan& sp : spans) {
      if (!scalar.march(ray, t0, sp.k0, sp.k1, a, false, &scanned)) break;
    }
    typename BatchMarch<DenseSampler<T, std::uint16_t>>::SpanScan q;
    bool alive = true;
    for (std::size_t j = 0; j < spans.size() && alive;) {
      const std::size_t n = std::min(spans.size() - j, std::size_t(1 + r.next() % 40u));
      alive = batch.scan_spans(ray, t0, spans.data() + j, int(n), b, q);
      j += n;
    }
    if (alive) alive = batch.scan_finish(ray, t0, b, q);
    RC_ASSERT(alive == !b.done);
    RC_ASSERT(same(a, b));
  }
}

RC_GTEST_PROP(SampleBatchProperty, MarchEqualsTheScalarMarchU8, (std::uint64_t seed)) { check_rays<std::uint8_t>(seed); }
RC_GTEST_PROP(SampleBatchProperty, MarchEqualsTheScalarMarchU16, (std::uint64_t seed)) {
  check_rays<std::uint16_t>(seed);
}

// Lane for lane: the batch's value, opacity and table coordinate of sample k+j are the scalar caster's
// (DenseGrid::sample, TransferFunctionView::coord / alpha_at), and without a mask every lane < n is set.
template <class T>
void check_lanes(std::uint64_t seed) {
  if (!sample_batch_available()) return;
  Rng r{seed};
  const RandomScene sc(r, SceneShape{sizeof(T) == 1 ? VoxelType::U8 : VoxelType::U16, 2, 5.0f});
  const float step = r.uni(0.1f, 1.5f);
  auto c = make_caster<T>(sc, step, r);
  const vec3 ext = sc.desc.extent();
  Ray ray;
  ray.origin = vec3(r.uni(-0.5f, 1.5f), r.uni(-0.5f, 1.5f), r.uni(-0.5f, 1.5f)) * ext;
  const vec3 dir = vec3(r.uni(0.0f, 1.0f), r.uni(0.0f, 1.0f), r.uni(0.0f, 1.0f)) * ext - ray.origin;
  if (!(glm::length(dir) > 1e-3f)) return;
  ray.dir = glm::normalize(dir);
  const float t_entry = r.uni(0.0f, 4.0f);
  DvrBatchArgs b;
  b.data = sc.vol.as<T>();
  b.elem_size = int(sizeof(T));
  b.dims = sc.desc.dims;
  b.inv_spacing = 1.0f / sc.desc.spacing;
  b.hi = vec3(sc.desc.dims - 1);
  b.bytes = std::int64_t(sc.desc.dims.x) * sc.desc.dims.y * sc.desc.dims.z * b.elem_size;
  b.origin = ray.origin;
  b.dir = ray.dir;
  b.t_entry = t_entry;
  b.dt = c.p.dt;
  b.tf_table = &c.p.tf.table[0].x;
  b.tf_size = c.p.tf.size;
  b.tf_vmin = c.p.tf.vmin;
  b.tf_inv_step = c.p.tf.inv_step;
  // Half the time from the bricked copy: the same lanes, and never a fallback (the bricks' allocation
  // has room for the last gather).
  const bool from_bricks = r.next() % 2 == 0;
  const BrickedVolume bricks(sc.vol.data(), sc.desc.dims, int(sizeof(T)));
  if (from_bricks) {
    b.bricks = bricks.data();
    b.brick_counts = bricks.bricks();
  }
  RC_ASSERT(sample_batch_fits(b));
  int fallbacks = 0;
  for (int k = 0; k < 200; k += 8) {
    const int n = 1 + int(r.next() % 8);
    DvrBatchOut o;
    const int visible = dvr_batch(b, k, n, o);
    if (visible < 0) {
      RC_ASSERT(!from_bricks);
      ++fallbacks;
      continue;
    }
    RC_ASSERT(visible == (1 << n) - 1);
    for (int j = 0; j < n; ++j) {
      const vec3 pos = ray.at(t_entry + float(k + j) * c.p.dt);
      const float v = c.volume.volume.sample(pos);
      const TransferFunctionView::Coord tc = c.p.tf.coord(v);
      const float a = c.p.tf.alpha_at(tc);
      RC_ASSERT(std::memcmp(&v, &o.v[j], sizeof(float)) == 0);
      RC_ASSERT(std::memcmp(&a, &o.alpha[j], sizeof(float)) == 0);
      RC_ASSERT(tc.i == o.i[j]);
      RC_ASSERT(std::memcmp(&tc.f, &o.f[j], sizeof(float)) == 0);
    }
  }
  RC_TAG(from_bricks ? "bricks" : fallbacks > 0 ? "rows, some fallback" : "rows, no fallback");
}

RC_GTEST_PROP(SampleBatchProperty, LanesAreTheScalarSamplesU8, (std::uint64_t seed)) { check_lanes<std::uint8_t>(seed); }
RC_GTEST_PROP(SampleBatchProperty, LanesAreTheScalarSamplesU16, (std::uint64_t seed)) {
  check_lanes<std::uint16_t>(seed);
}

// The batch reports lanes whose voxels reach the volume's last bytes instead of gathering past them.
TEST(SampleBatch, TheLastVoxelFallsBackToTheScalarPath) {
  if (!sample_batch_available()) GTEST_SKIP() << "this CPU has no AVX2: the scalar path is the only one";
  VolumeDesc d;
  d.dims = ivec3(3, 3, 3);
  Volume v(d);
  for (int i = 0; i < 27; ++i) v.as<std::uint8_t>()[i] = std::uint8_t(i * 9);
  const TransferFunction tf({{0.0f, vec4(0.0f)}, {255.0f, vec4(1.0f)}});
  const TransferFunctionView tv = tf.view(1.0f);
  DvrBatchArgs b;
  b.data = v.as<std::uint8_t>();
  b.dims = d.dims;
  b.hi = vec3(2.0f);
  b.bytes = 27;
  b.dir = vec3(1.0f, 0.0f, 0.0f);
  b.dt = 0.25f;
  b.tf_table = &tv.table[0].x;
  b.tf_size = tv.size;
  b.tf_vmin = tv.vmin;
  b.tf_inv_step = tv.inv_step;
  ASSERT_TRUE(sample_batch_fits(b));
  DvrBatchOut o;
  b.origin = vec3(0.0f, 0.5f, 0.5f);  // the first row: far from the end
  EXPECT_EQ(dvr_batch(b, 0, 8, o), 0xFF);
  EXPECT_EQ(o.v[0], 0.0f);
  b.origin = vec3(0.0f, 2.9f, 2.9f);  // the last row: the gather at its last voxels would pass the end
  EXPECT_EQ(dvr_batch(b, 0, 8, o), -1);
  b.bytes = 26;  // not the dims' size: refused
  EXPECT_FALSE(sample_batch_fits(b));
}

}  // namespace
}  // namespace sl
