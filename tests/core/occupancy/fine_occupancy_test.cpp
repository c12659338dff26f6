// The fine occupancy grid (core/occupancy/fine_occupancy.h): skipping the grid samples of clear cells inside a
// sampled span leaves every ray's result bit for bit as it was, and only removes samples.
#include "core/occupancy/fine_occupancy.h"

#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <type_traits>

#include "core/occupancy/block_metadata.h"
#include "core/occupancy/culling.h"
#include "core/util/error.h"
#include "core/occupancy/occupancy_geometry.h"
#include "core/occupancy/occupancy_tree.h"
#include "core/cast/raycast.h"
#include "tests/core/random_scene.h"

namespace sl {
namespace {

using test_scene::RandomScene;
using test_scene::Rng;

RC_GTEST_PROP(FineOccupancyProperty, SkippingClearCellsChangesNoRay, (std::uint64_t seed)) {
  Rng r{seed};
  RandomScene sc(r);
  const int cell = r.next() % 2 ? 4 : 8;
  const RenderMode modes[] = {RenderMode::Dvr, RenderMode::Labels, RenderMode::Mip};
  const RenderMode mode = modes[r.next() % 3];
  const VolumeView lv = sc.lab.view();
  const BlockMetadataTable cells = compute_all_block_metadata(make_block_grid(sc.desc.dims, sc.desc.spacing, cell),
                                                              sc.vol.view(), &lv);
  CullParams cull;
  cull.mode = mode;
  cull.tf = &sc.tf;
  cull.enabled = (sc.use_labels || mode == RenderMode::Labels) ? &sc.enabled : nullptr;
  FineOccupancy fine;
  fine.classify(cells, cull);
  const FineOccupancyView fv = fine.view();
  // And with the voxel mask inside the occupied cells (DVR and labels modes).
  FineOccupancyView fm = fv;
  VoxelMask mask;
  if (mode != RenderMode::Mip) {
    mask.build(sc.vol.view(), &lv, cull);
    fm.voxels = mask.view();
  }

  const float step = r.uni(0.2f, 1.5f);
  RayCaster<DenseSampler<std::uint8_t, std::uint16_t>> caster;
  caster.p.mode = mode;
  caster.p.dt = step * sc.desc.min_spacing();
  caster.p.inv_dt = 1.0f / caster.p.dt;
  caster.p.spacing = sc.desc.spacing;
  caster.p.tf = sc.tf.view(step);
  caster.p.label_mask = sc.use_labels && mode != RenderMode::Labels;
  caster.p.labels = sc.enabled.view();
  caster.p.ert = r.next() % 2 == 0;
  caster.volume.volume = DenseGrid<std::uint8_t>{sc.vol.as<std::uint8_t>(), sc.desc.dims, 1.0f / sc.desc.spacing};
  caster.volume.labels = DenseGrid<std::uint16_t>{sc.lab.as<std::uint16_t>(), sc.desc.dims, 1.0f / sc.desc.spacing};

  const vec3 ext = sc.desc.extent();
  const Box3 vbox{vec3(0.0f), ext};
  for (int i = 0; i < 20; ++i) {
    Ray ray;
    // Origins outside and inside the box; directions with axis-parallel components now and then.
    ray.origin = vec3(r.uni(-0.5f, 1.5f), r.uni(-0.5f, 1.5f), r.uni(-0.5f, 1.5f)) * ext;
    const vec3 target = vec3(r.uni(0.1f, 0.9f), r.uni(0.1f, 0.9f), r.uni(0.1f, 0.9f)) * ext;
    vec3 dir = target - ray.origin;
    if (r.next() % 5 == 0) dir[int(r.next() % 3)] = 0.0f;
    if (!(glm::length(dir) > 1e-3f)) continue;
    ray.dir = glm::normalize(dir);
    const Interval iv = intersect(ray, vbox);
    const float t0 = iv.t0 > 0.0f ? iv.t0 : 0.0f;
    if (!(iv.t1 > t0)) continue;
    const int k_end = sample_index(iv.t1, t0, caster.p.inv_dt);
    // A random sub-span, as a segment list hands the caster.
    const int k0 = int(r.next() % std::uint64_t(k_end + 1));
    const int k1 = k0 + int(r.next() % std::uint64_t(k_end - k0 + 1));
    RayAccum plain, skipped, masked;
    caster.march(ray, t0, k0, k1, plain);
    caster.march(ray, t0, k0, k1, skipped, false, &fv);
    caster.march(ray, t0, k0, k1, masked, false, &fm);
    for (const RayAccum* a : {&skipped, &masked}) {
      RC_ASSERT(std::memcmp(&plain.color, &a->color, sizeof(vec3)) == 0);
      RC_ASSERT(std::memcmp(&plain.alpha, &a->alpha, sizeof(float)) == 0);
      RC_ASSERT(std::memcmp(&plain.hit_t, &a->hit_t, sizeof(float)) == 0);
      RC_ASSERT(plain.mip_any == a->mip_any);
      if (plain.mip_any) RC_ASSERT(plain.mip_max == a->mip_max);
      RC_ASSERT(plain.useful_samples == a->useful_samples);
      RC_ASSERT(plain.done == a->done);
    }
    RC_ASSERT(skipped.samples <= plain.samples);
    RC_ASSERT(masked.samples <= skipped.samples);
    // Every sample the mask leaves out was one that contributed nothing.
    RC_ASSERT(masked.samples >= masked.useful_samples);
  }
}

// The voxel mask's bit of every trilinear cell is classify_block's test of the cell's own metadata:
// the range and labels of the (up to) 8 voxels a sample in it blends, clamped at the faces as
// DenseGrid::sample clamps; for u8 and u16 volumes, with and without labels, DVR and labels modes.
template <class T>
void check_mask_is_the_cells_culling_test(Rng& r) {
  RandomScene sc(r);
  VolumeDesc d = sc.desc;
  d.type = std::is_same_v<T, std::uint8_t> ? VoxelType::U8 : VoxelType::U16;
  Volume vol(d);
  const float scale = std::is_same_v<T, std::uint8_t> ? 1.0f : 200.0f;  // u16: values up to ~53,000
  for (int z = 0; z < d.dims.z; ++z)
    for (int y = 0; y < d.dims.y; ++y)
      for (int x = 0; x < d.dims.x; ++x) vol.set(x, y, z, sc.vol.value(x, y, z) * scale);
  const float cut = r.uni(0.0f, 250.0f) * scale;
  const TransferFunction tf({{0.0f, vec4(0.0f)}, {cut, vec4(0.0f)}, {cut + 0.5f, vec4(0.5f)}, {255.0f * scale, vec4(1.0f)}});
  CullParams cull;
  cull.mode = r.next() % 2 ? RenderMode::Dvr : RenderMode::Labels;
  cull.tf = &tf;
  cull.enabled = sc.use_labels || cull.mode == RenderMode::Labels ? &sc.enabled : nullptr;
  const VolumeView lv = sc.lab.view();
  VoxelMask mask;
  mask.build(vol.view(), &lv, cull);
  const VoxelMaskView m = mask.view();
  std::size_t set = 0;
  for (int z = 0; z < d.dims.z; ++z)
    for (int y = 0; y < d.dims.y; ++y)
      for (int x = 0; x < d.dims.x; ++x) {
        BlockMetadata md;
        md.computed = true;
        md.has_labels = true;
        md.min = 1e30f;
        md.max = -1e30f;
        for (int c = 0; c < 8; ++c) {
          const int vx = std::min(x + (c & 1), d.dims.x - 1), vy = std::min(y + ((c >> 1) & 1), d.dims.y - 1);
          const int vz = std::min(z + ((c >> 2) & 1), d.dims.z - 1);
          md.min = std::min(md.min, vol.value(vx, vy, vz));
          md.max = std::max(md.max, vol.value(vx, vy, vz));
          md.labels.push_back(sc.lab.label(vx, vy, vz));
        }
        std::sort(md.labels.begin(), md.labels.end());
        md.labels.erase(std::unique(md.labels.begin(), md.labels.end()), md.labels.end());
        const bool want = classify_block(md, cull) != OccupancyClass::Empty;
        // The cell's centre point, through the view's own lookup.
        const vec3 p = (vec3(x, y, z) + 1.0f) * d.spacing;
        const std::size_t row = std::size_t(z) * std::size_t(d.dims.y) + std::size_t(y);
        const bool bit = ((m.bits[row * std::size_t(m.row_words) + std::size_t(x >> 6)] >> (x & 63)) & 1u) != 0u;
        RC_ASSERT(bit == want);
        if (x + 1 < d.dims.x && y + 1 < d.dims.y && z + 1 < d.dims.z) RC_ASSERT(m.visible(p) == want);
        set += want ? 1u : 0u;
      }
  RC_ASSERT(mask.set_cells() == set);
}

RC_GTEST_PROP(FineOccupancyProperty, VoxelMaskBitIsTheCullingTestOfTheCellU8, (std::uint64_t seed)) {
  Rng r{seed};
  check_mask_is_the_cells_culling_test<std::uint8_t>(r);
}

RC_GTEST_PROP(FineOccupancyProperty, VoxelMaskBitIsTheCullingTestOfTheCellU16, (std::uint64_t seed)) {
  Rng r{seed};
  check_mask_is_the_cells_culling_test<std::uint16_t>(r);
}

// A clear bit holds for any point of its cell: a sample there is transparent or its label is off.
RC_GTEST_PROP(FineOccupancyProperty, SamplesInClearVoxelCellsContributeNothing, (std::uint64_t seed)) {
  Rng r{seed};
  RandomScene sc(r);
  CullParams cull;
  cull.tf = &sc.tf;
  cull.enabled = sc.use_labels ? &sc.enabled : nullptr;
  const VolumeView lv = sc.lab.view();
  VoxelMask mask;
  mask.build(sc.vol.view(), &lv, cull);
  const VoxelMaskView m = mask.view();
  const DenseGrid<std::uint8_t> iv{sc.vol.as<std::uint8_t>(), sc.desc.dims, 1.0f / sc.desc.spacing};
  const DenseGrid<std::uint16_t> lg{sc.lab.as<std::uint16_t>(), sc.desc.dims, 1.0f / sc.desc.spacing};
  const TransferFunctionView tv = sc.tf.view(1.0f);
  const vec3 ext = sc.desc.extent();
  int clear = 0;
  for (int i = 0; i < 2000; ++i) {
    const vec3 p = vec3(r.uni(0.0f, 1.0f), r.uni(0.0f, 1.0f), r.uni(0.0f, 1.0f)) * ext;
    if (m.visible(p)) continue;
    ++clear;
    const float a = tv.alpha_at(tv.coord(iv.sample(p)));
    const bool label_on = sc.enabled.enabled(lg.label_at(p));
    RC_ASSERT(!(a > 0.0f) || (sc.use_labels && !label_on));
  }
  RC_TAG(clear > 0 ? "some clear" : "none clear");
}

TEST(VoxelMask, OnlyU8AndU16VolumesAndDvrOrLabels) {
  VolumeDesc d;
  d.dims = ivec3(4);
  d.type = VoxelType::F32;
  const Volume f(d);
  EXPECT_FALSE(VoxelMask::supported(f.view()));
  d.type = VoxelType::U16;
  const Volume u(d);
  EXPECT_TRUE(VoxelMask::supported(u.view()));
  CullParams cull;
  cull.mode = RenderMode::Iso;
  VoxelMask m;
  EXPECT_THROW(m.build(u.view(), nullptr, cull), std::logic_error);
  EXPECT_THROW(m.build(f.view(), nullptr, CullParams{}), std::logic_error);
  // No transfer function: every cell is visible; rows padded to whole words.
  m.build(u.view(), nullptr, CullParams{});
  EXPECT_EQ(m.set_cells(), 64u);
  EXPECT_EQ(m.view().row_words, 1);
  EXPECT_EQ(m.bytes(), 16u * 8u);
}

// The margin the walk relies on: points up to (almost) half a voxel outside a clear cell, in the
// volume, still sample only the cell's dilated footprint, so they contribute nothing either.
// tighten_leaf_boxes: only NON_EMPTY leaf boxes change, each within its own extent, and every point of
// the original box whose trilinear cell is set (the only samples the caster fetches under the mask)
// lies in the shrunk one — random points, points on and next to the cells' boundary planes, the
// box's corners.
RC_GTEST_PROP(FineOccupancyProperty, TightLeafBoxesHoldEverySampleOfASetCell, (std::uint64_t seed)) {
  Rng r{seed};
  RandomScene sc(r);
  const int block = 4 << (r.next() % 3);
  const VolumeView lv = sc.lab.view();
  const BlockMetadataTable md = compute_all_block_metadata(make_block_grid(sc.desc.dims, sc.desc.spacing, block),
                                                           sc.vol.view(), &lv);
  CullParams cull;
  cull.mode = r.next() % 2 ? RenderMode::Dvr : RenderMode::Labels;
  cull.tf = &sc.tf;
  cull.enabled = sc.use_labels || cull.mode == RenderMode::Labels ? &sc.enabled : nullptr;
  const std::vector<OccupancyClass> classes = classify_blocks(md, cull);
  const OccupancyTree tree = OccupancyTree::from_block_classes(md.grid, classes);
  const OccupancyGeometry g = build_occupancy_geometry(tree);
  VoxelMask mask;
  mask.build(sc.vol.view(), &lv, cull);
  const VoxelMaskView m = mask.view();
  const OccupancyGeometry t = tighten_leaf_boxes(tree, g, m);
  RC_ASSERT(t.boxes.size() == g.boxes.size());
  const auto inside = [](const Box3& b, const vec3& p) {
    return p.x >= b.lo.x && p.x <= b.hi.x && p.y >= b.lo.y && p.y <= b.hi.y && p.z >= b.lo.z && p.z <= b.hi.z;
  };
  std::size_t shrunk = 0, checked = 0;
  for (std::size_t i = 0; i < g.boxes.size(); ++i) {
    const Box3 &b = g.boxes[i].box, &tb = t.boxes[i].box;
    RC_ASSERT(t.boxes[i].cls == g.boxes[i].cls && t.boxes[i].parent_cls == g.boxes[i].parent_cls &&
              t.boxes[i].node == g.boxes[i].node);
    const bool leaf = g.boxes[i].cls == OccupancyClass::NonEmpty && effective_leaf(tree, g, g.boxes[i].node);
    if (!leaf) {
      RC_ASSERT(std::memcmp(&b, &tb, sizeof(Box3)) == 0);
      continue;
    }
    for (int a = 0; a < 3; ++a) RC_ASSERT(tb.lo[a] >= b.lo[a] && tb.hi[a] <= b.hi[a] && tb.lo[a] <= tb.hi[a]);
    shrunk += std::memcmp(&b, &tb, sizeof(Box3)) != 0 ? 1u : 0u;
    const auto check = [&](vec3 p) {
      p = glm::clamp(p, b.lo, b.hi);
      if (!m.visible(p)) return;
      ++checked;
      RC_ASSERT(inside(tb, p));
    };
    for (int c = 0; c < 8; ++c) check(vec3(c & 1 ? b.hi.x : b.lo.x, c & 2 ? b.hi.y : b.lo.y, c & 4 ? b.hi.z : b.lo.z));
    for (int n = 0; n < 64; ++n) {
      vec3 p(r.uni(b.lo.x, b.hi.x), r.uni(b.lo.y, b.hi.y), r.uni(b.lo.z, b.hi.z));
      check(p);
      // On a cell boundary plane (voxel coordinate k + 1/2) of one axis, and one float either side.
      const int a = int(r.next() % 3);
      const float k = std::floor(p[a] / sc.desc.spacing[a] - 0.5f) + float(r.next() % 2);
      p[a] = (k + 0.5f) * sc.desc.spacing[a];
      check(p);
      vec3 q = p;
      q[a] = std::nextafter(p[a], -1e30f);
      check(q);
      q[a] = std::nextafter(p[a], 1e30f);
      check(q);
    }
  }
  RC_TAG(shrunk > 0 ? "shrunk" : "unchanged");
  RC_TAG(checked > 0 ? "set samples checked" : "no set sample");
}

RC_GTEST_PROP(FineOccupancyProperty, HalfVoxelMarginOfClearCells, (std::uint64_t seed)) {
  Rng r{seed};
  RandomScene sc(r);
  const BlockGrid g = make_block_grid(sc.desc.dims, sc.desc.spacing, 4);
  const VolumeView lv = sc.lab.view();
  const BlockMetadataTable cells = compute_all_block_metadata(g, sc.vol.view(), &lv);
  CullParams cull;
  cull.tf = &sc.tf;
  cull.enabled = sc.use_labels ? &sc.enabled : nullptr;
  FineOccupancy fine;
  fine.classify(cells, cull);
  const FineOccupancyView fv = fine.view();
  DenseGrid<std::uint8_t> iv{sc.vol.as<std::uint8_t>(), sc.desc.dims, 1.0f / sc.desc.spacing};
  DenseGrid<std::uint16_t> lg{sc.lab.as<std::uint16_t>(), sc.desc.dims, 1.0f / sc.desc.spacing};
  const TransferFunctionView tv = sc.tf.view(1.0f);
  for (std::size_t i = 0; i < g.block_count(); ++i) {
    const ivec3 c = g.block_coord(i);
    if (fv.occupied(c)) continue;
    const Box3 b = g.block_box(c);
    for (int k = 0; k < 30; ++k) {
      const vec3 f(r.uni(-0.49f, 1.49f), r.uni(-0.49f, 1.49f), r.uni(-0.49f, 1.49f));
      vec3 pos = b.lo + (b.hi - b.lo) * vec3(glm::clamp(f, 0.0f, 1.0f));
      pos += (f - glm::clamp(f, 0.0f, 1.0f)) * sc.desc.spacing;  // up to 0.49 voxel outside
      pos = glm::clamp(pos, vec3(0.0f), sc.desc.extent());
      const bool visible = !sc.use_labels || sc.enabled.enabled(lg.label_at(pos));
      RC_ASSERT(!visible || tv.lookup(iv.sample(pos)).a == 0.0f);
    }
  }
}

TEST(FineOccupancy, CellSizesAndBits) {
  EXPECT_NO_THROW(validate_fine_cell(0));
  EXPECT_NO_THROW(validate_fine_cell(4));
  EXPECT_NO_THROW(validate_fine_cell(8));
  EXPECT_THROW(validate_fine_cell(16), InputError);
  EXPECT_THROW(validate_fine_cell(-4), InputError);
  EXPECT_NO_THROW(validate_fine_cell(kFineCellAuto));
  EXPECT_EQ(resolve_fine_cell(kFineCellAuto, true), 8);  // the voxel mask culls sample by sample
  EXPECT_EQ(resolve_fine_cell(kFineCellAuto, false), 4);
  EXPECT_EQ(resolve_fine_cell(4, true), 4);
  EXPECT_EQ(resolve_fine_cell(0, true), 0);
  // One bright voxel in the middle of a dark 16³ volume: only the cells whose dilated footprint
  // holds it are set.
  VolumeDesc d;
  d.dims = ivec3(16);
  Volume v(d);
  v.set(8, 8, 8, 255.0f);
  const BlockMetadataTable cells = compute_all_block_metadata(make_block_grid(d.dims, d.spacing, 4), v.view(), nullptr);
  const TransferFunction tf({{0.0f, vec4(0.0f)}, {100.0f, vec4(0.0f)}, {255.0f, vec4(1.0f)}});
  CullParams cull;
  cull.tf = &tf;
  FineOccupancy fine;
  fine.classify(cells, cull);
  EXPECT_EQ(fine.cell_count(), 64u);
  // Voxel 8 lies in cell 2 and in the dilated footprint of cell 1 (voxels 3..8): 2³ cells.
  EXPECT_EQ(fine.set_cells(), 8u);
  EXPECT_TRUE(fine.view().occupied(ivec3(1, 2, 1)));
  EXPECT_FALSE(fine.view().occupied(ivec3(0, 0, 0)));
  EXPECT_FALSE(fine.view().occupied(ivec3(3, 2, 2)));
  EXPECT_EQ(fine.view().cell_of(vec3(-0.5f, 8.0f, 15.99f)), ivec3(0, 2, 3));
}

}  // namespace
}  // namespace sl
