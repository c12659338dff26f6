// The max pyramid (cache/pyramid.h PyramidKind::Max): sparse structure stays visible at every level.
// A one-voxel-thin line through a random small volume keeps at least its value in every coarse voxel
// it crosses, in the pyramid and in the bricks the source serves, where the mean pyramid averages it
// towards the background.
#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include <cmath>
#include <memory>
#include <vector>

#include "core/scene/camera.h"
#include "core/scene/transfer_function.h"
#include "core/util/error.h"
#include "cache/pyramid.h"
#include "cache/volume_source.h"
#include "cache/out_of_core/renderer.h"
#include "cache/synthetic/procedural_neurites.h"

namespace sl {
namespace {

struct Line {
  std::shared_ptr<Volume> volume;
  std::vector<ivec3> voxels;  // the level-0 voxels on the line
  float value = 0.0f;
};

// A random volume of 2..48 voxels a side with a dimmer random background (or none) and a line of
// `value` from a random point in a random direction, one voxel thin (each sample sets the voxel it
// falls in).
Line random_line() {
  const ivec3 dims(*rc::gen::inRange(2, 49), *rc::gen::inRange(2, 49), *rc::gen::inRange(2, 49));
  const VoxelType type = *rc::gen::element(VoxelType::U8, VoxelType::U16, VoxelType::F32);
  Line l;
  l.value = float(*rc::gen::inRange(1, 256));
  const int background = *rc::gen::inRange(0, int(l.value));  // below the line's value
  l.volume = std::make_shared<Volume>(VolumeDesc{dims, vec3(1.0f), type});
  const unsigned seed = *rc::gen::arbitrary<unsigned>();
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x) {
        const unsigned h = (unsigned(x) * 73856093u) ^ (unsigned(y) * 19349663u) ^ (unsigned(z) * 83492791u) ^ seed;
        l.volume->set(x, y, z, float(h % unsigned(background + 1)));
      }
  const auto unit = rc::gen::inRange(0, 1001);
  vec3 p = vec3(dims) * vec3(*unit, *unit, *unit) / 1000.0f;
  vec3 d(*unit - 500, *unit - 500, *unit - 500);
  d = glm::length(d) > 0.0f ? glm::normalize(d) : vec3(1.0f, 0.0f, 0.0f);
  const int steps = *rc::gen::inRange(1, 400);
  for (int i = 0; i < steps; ++i, p += d * 0.25f) {
    const ivec3 v(glm::floor(p));
    if (glm::any(glm::lessThan(v, ivec3(0))) || glm::any(glm::greaterThanEqual(v, dims))) continue;
    l.volume->set(v.x, v.y, v.z, l.value);
    l.voxels.push_back(v);
  }
  return l;
}

RC_GTEST_PROP(MaxPyramid, OneVoxelThinLineStaysVisibleAtEveryLevel, ()) {
  const Line line = random_line();
  RC_PRE(!line.voxels.empty());
  const MemoryVolumeSource src(line.volume, nullptr, "line", PyramidKind::Max);
  const int brick = *rc::gen::element(8, 16);
  const BrickLayout layout = BrickLayout::make(line.volume->desc(), brick);
  std::vector<std::byte> out(std::size_t(layout.stored_voxels()) * std::size_t(voxel_size(line.volume->type())));
  for (int level = 1; level < layout.levels; ++level) {
    const Volume& max = src.max_level(level);
    for (const ivec3 v0 : line.voxels) {
      const ivec3 v = v0 >> level;
      RC_ASSERT(max.value(v.x, v.y, v.z) >= line.value);
    }
    // What the renderer samples: the served brick holding the line's first voxel at this level.
    const ivec3 v = line.voxels.front() >> level;
    const BrickId id = BrickId::pack(level, v / brick);
    src.read_brick(layout, id, out, {});
    const ivec3 s = v - layout.brick_origin(id) + kBrickApron;  // stored voxel (apron first)
    const int n = layout.stored_size();
    const VolumeView bv{out.data(), ivec3(n), vec3(1.0f), line.volume->type()};
    RC_ASSERT(bv.value(s.x, s.y, s.z) >= line.value);
  }
}

// What the max pyramid is for: a line along x over an empty background fills 1 / 4^l of each level-l
// voxel it crosses, so the mean fades it fourfold per level while the max keeps its value.
TEST(MaxPyramid, MeanPyramidFadesALineTheMaxKeeps) {
  auto v = std::make_shared<Volume>(VolumeDesc{ivec3(64), vec3(1.0f), VoxelType::U8});
  for (int x = 0; x < 64; ++x) v->set(x, 17, 40, 200.0f);
  const MemoryVolumeSource mean(v, nullptr, "line", PyramidKind::Mean);
  const MemoryVolumeSource max(v, nullptr, "line", PyramidKind::Max);
  EXPECT_EQ(mean.pyramid(), PyramidKind::Mean);
  EXPECT_EQ(max.pyramid(), PyramidKind::Max);
  for (int level = 1; level < mean.levels(); ++level) {
    const ivec3 c = ivec3(5, 17, 40) >> level;
    EXPECT_EQ(max.max_level(level).value(c.x, c.y, c.z), 200.0f) << level;
    // A line along x fills 1 / 4^l of each voxel it crosses.
    EXPECT_NEAR(mean.level(level).value(c.x, c.y, c.z), std::floor(200.0 / double(1 << (2 * level)) + 0.5), 1.0) << level;
  }
  // Bricks of the two sources differ exactly at the coarse levels.
  const BrickLayout layout = BrickLayout::make(v->desc(), 8);
  std::vector<std::byte> a(std::size_t(layout.stored_voxels())), b(a.size());
  for (int level = 0; level < layout.levels; ++level) {
    const BrickId id = BrickId::pack(level, (ivec3(5, 17, 40) >> level) / 8);
    mean.read_brick(layout, id, a, {});
    max.read_brick(layout, id, b, {});
    EXPECT_EQ(a == b, level == 0) << level;
  }
}

// Rendering, a pinned coarse level out of core: the procedural source's max pyramid renders the image
// of a MemoryVolumeSource's max pyramid of the same level-0 voxels, pixel for pixel (same bricks, and
// block bounds that agree with them), and shows more than the mean pyramid of those voxels.
TEST(MaxPyramid, PinnedLevelRendersAlikeFromProceduralAndMemorySources) {
  const ivec3 dims(160, 128, 96);
  auto procedural = std::make_shared<ProceduralNeuritesSource>(dims, 7, "p", PyramidKind::Max);
  auto vol = std::make_shared<Volume>(VolumeDesc{dims, vec3(1.0f), VoxelType::U8});
  auto lab = std::make_shared<Volume>(VolumeDesc{dims, vec3(1.0f), VoxelType::U32});
  procedural->synthesize(0, ivec3(0), dims, vol->as<std::uint8_t>(), lab->as<std::uint32_t>());
  const TransferFunction tf = default_transfer_function(0.0f, 255.0f);
  const Camera cam = default_camera(vol->desc().extent());
  RenderSettings rs;
  rs.width = 96;
  rs.height = 80;
  const auto converged = [&](std::shared_ptr<const VolumeSource> src, int level) {
    OutOfCoreSettings os;
    os.cache_mb = 64;
    os.lod = level;
    OutOfCoreRenderer r(std::move(src), os, 16);
    Frame f;
    for (int i = 0; i < 40; ++i) {
      f = r.render(OutOfCoreScene{&tf, nullptr, cam}, rs);
      if (r.converged()) break;
      r.wait_for_loads();
    }
    EXPECT_TRUE(r.converged());
    return f.image.rgba;
  };
  const auto lit = [](const std::vector<vec4>& rgba) {
    std::size_t n = 0;
    for (const vec4& p : rgba) n += p.a > 0.05f;
    return n;
  };
  for (const int level : {1, 2}) {
    SCOPED_TRACE("level " + std::to_string(level));
    const auto p = converged(procedural, level);
    const auto m = converged(std::make_shared<MemoryVolumeSource>(vol, lab, "m", PyramidKind::Max), level);
    const auto mean = converged(std::make_shared<MemoryVolumeSource>(vol, lab, "m", PyramidKind::Mean), level);
    EXPECT_TRUE(p == m);
    EXPECT_GT(lit(p), lit(mean));
  }
}

TEST(MaxPyramid, ParsesKinds) {
  EXPECT_EQ(parse_pyramid_kind("mean", "--pyramid"), PyramidKind::Mean);
  EXPECT_EQ(parse_pyramid_kind("max", "--pyramid"), PyramidKind::Max);
  EXPECT_STREQ(pyramid_name(PyramidKind::Max), "max");
  EXPECT_THROW(parse_pyramid_kind("median", "--pyramid"), InputError);
}

}  // namespace
}  // namespace sl
