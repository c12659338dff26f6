#include "cache/brick_cache.h"

#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include <bit>
#include <cstring>
#include <memory>
#include <thread>
#include <vector>

#include "cache/page_table.h"
#include "cache/volume_source.h"
#include "core/util/error.h"
#include "core/recon/sampling.h"

namespace sl {
namespace {

std::shared_ptr<Volume> random_volume(ivec3 dims, VoxelType t, std::uint32_t seed) {
  auto v = std::make_shared<Volume>(VolumeDesc{dims, vec3(1.0f), t});
  const std::uint32_t hi = t == VoxelType::U8 ? 256 : 65536;
  std::uint32_t h = seed * 2654435761u + 1;
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x) {
        h ^= h << 13;  // xorshift32: arbitrary but reproducible values
        h ^= h >> 17;
        h ^= h << 5;
        const float r = float(h % hi);
        v->set(x, y, z, t == VoxelType::F32 ? r * 0.013f - 300.0f : r);
      }
  return v;
}

template <class T>
DenseGrid<T> grid_of(const Volume& v, vec3 spacing) {
  DenseGrid<T> g;
  g.data = v.as<T>();
  g.dims = v.dims();
  g.inv_spacing = 1.0f / spacing;  // as the CPU and CUDA renderers build it
  return g;
}

// Random points in a brick's payload region (the part inside the volume), sampled through a cache
// slot and through DenseGrid over the whole level: bit-identical at level 0 (apron voxels included,
// since points near the payload faces interpolate into them), and equal at every coarser level
// against a DenseGrid over that level's volume.
template <class T>
void check_slot_sampling(VoxelType t) {
  const ivec3 dims(*rc::gen::inRange(1, 60), *rc::gen::inRange(1, 60), *rc::gen::inRange(1, 60));
  const int b = *rc::gen::element(8, 16);
  const vec3 spacing(*rc::gen::element(1.0f, 0.5f, 0.3f), *rc::gen::element(1.0f, 2.0f), 1.0f);
  auto vol = random_volume(dims, t, *rc::gen::arbitrary<std::uint32_t>());
  vol->set_spacing(spacing);
  const MemoryVolumeSource src(vol);
  const BrickLayout layout = BrickLayout::make(src.desc(), b);
  const int level = *rc::gen::inRange(0, layout.levels);
  const ivec3 nb = layout.bricks(level);
  const BrickId id = BrickId::pack(level, {*rc::gen::inRange(0, nb.x), *rc::gen::inRange(0, nb.y),
                                           *rc::gen::inRange(0, nb.z)});
  BrickCache cache(layout, t, std::nullopt, 4);
  const auto a = cache.allocate(id, 1);
  RC_ASSERT(a.has_value());
  src.read_brick(layout, id, cache.slot_voxels(a->slot), {});
  const BrickCacheView view = cache.view();
  const SlotSampler<T> s = view.sampler<T>(a->slot, layout, id);
  const DenseGrid<T> dense = grid_of<T>(src.level(level), layout.level_spacing(level));
  const WorldBox box = layout.brick_box(id);
  for (int i = 0; i < 64; ++i) {
    const auto u = rc::gen::inRange(0, 1 << 16);
    const vec3 f = vec3(float(*u), float(*u), float(*u)) / float(1 << 16);
    const vec3 p = box.lo + f * (box.hi - box.lo);
    const float want = dense.sample(p), got = s.sample(p);
    RC_ASSERT(std::bit_cast<std::uint32_t>(want) == std::bit_cast<std::uint32_t>(got));
  }
}

RC_GTEST_PROP(BrickCache, SlotSamplingEqualsDenseU8, ()) { check_slot_sampling<std::uint8_t>(VoxelType::U8); }
RC_GTEST_PROP(BrickCache, SlotSamplingEqualsDenseU16, ()) { check_slot_sampling<std::uint16_t>(VoxelType::U16); }
RC_GTEST_PROP(BrickCache, SlotSamplingEqualsDenseF32, ()) { check_slot_sampling<float>(VoxelType::F32); }

// The whole translation chain at every level: world point -> brick_at -> page table -> slot ->
// sample, for a cache holding every brick, against DenseGrid over each level's volume.
TEST(BrickCache, TranslationChainAtEveryLevel) {
  const ivec3 dims(97, 131, 73);
  auto vol = std::make_shared<Volume>(VolumeDesc{dims, vec3(1.0f), VoxelType::U16});
  auto lab = std::make_shared<Volume>(VolumeDesc{dims, vec3(1.0f), VoxelType::U32});
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x) {
        vol->set(x, y, z, float((x * x + 3 * y + 7 * z * y) % 4001));
        lab->set(x, y, z, float((x / 5 + y / 7 + z / 3) % 9));
      }
  const MemoryVolumeSource src(vol, lab);
  const BrickLayout layout = BrickLayout::make(src.desc(), 16);
  PageTable pt(layout);
  BrickCache cache(layout, VoxelType::U16, VoxelType::U32, 64);
  for (int level = 0; level < layout.levels; ++level) {
    const ivec3 n = layout.bricks(level);
    for (int z = 0; z < n.z; ++z)
      for (int y = 0; y < n.y; ++y)
        for (int x = 0; x < n.x; ++x) {
          const BrickId id = BrickId::pack(level, {x, y, z});
          const auto a = cache.allocate(id, 1);
          ASSERT_TRUE(a.has_value());
          src.read_brick(layout, id, cache.slot_voxels(a->slot), cache.slot_labels(a->slot));
          pt.set(id, PageEntry::resident(a->slot));
        }
  }
  const PageTableView ptv = pt.view();
  const BrickCacheView view = cache.view();
  for (int level = 0; level < layout.levels; ++level) {
    const DenseGrid<std::uint16_t> dense = grid_of<std::uint16_t>(src.level(level), layout.level_spacing(level));
    const DenseGrid<std::uint32_t> dlab = grid_of<std::uint32_t>(*src.label_level(level), layout.level_spacing(level));
    for (int i = 0; i < 4000; ++i) {
      // Deterministic scatter over the volume box, including its faces.
      const std::int64_t k = i;
      const vec3 f(float(k * 7919 % 1000) / 999.0f, float(k * 104729 % 1000) / 999.0f,
                   float(k * 1299709 % 1000) / 999.0f);
      const vec3 p = f * vec3(dims);
      const BrickId id = layout.brick_at(level, p);
      const PageEntry e = ptv.lookup(id);
      ASSERT_TRUE(e.is_resident());
      ASSERT_EQ(cache.brick_in(e.slot()), id);
      ASSERT_EQ(view.sampler<std::uint16_t>(e.slot(), layout, id).sample(p), dense.sample(p)) << level;
      ASSERT_EQ(view.label_sampler<std::uint32_t>(e.slot(), layout, id).label_at(p), dlab.label_at(p)) << level;
    }
  }
}

// Distinct level-0 bricks of the 97x131x73, B = 32 layout (4 x 5 x 3 bricks).
BrickId brick(int k) { return BrickId::pack(0, {k % 4, k / 4 % 5, k / 20}); }

TEST(BrickCache, SlotCountFromBudget) {
  const BrickLayout layout = BrickLayout::make(ivec3(97, 131, 73), vec3(1.0f), 32);
  // u8 voxels 34³ = 39304 B -> 39360 (64-byte rows); u32 labels 157216 B -> 157248; the voxel mask,
  // a bit per stored voxel: 39304 bits -> 615 words -> 616 (64-byte lines) = 4928 B; 201536 B/slot.
  const BrickCache c(layout, VoxelType::U8, VoxelType::U32, 1);
  EXPECT_EQ(c.slot_bytes(), 201536u);
  EXPECT_EQ(c.slot_count(), 5u);
  EXPECT_EQ(c.resident_count(), 0u);
  EXPECT_TRUE(c.has_labels());
  BrickCache no_labels(layout, VoxelType::U8, std::nullopt, 1);
  EXPECT_EQ(no_labels.slot_count(), (1u << 20) / (39360u + 4928u));
  EXPECT_EQ(no_labels.slot_mask(0).size(), 616u);
  // A float volume has no voxel mask.
  const BrickCache f32(layout, VoxelType::F32, std::nullopt, 1);
  EXPECT_FALSE(f32.masks_supported());
  EXPECT_EQ(f32.slot_bytes(), 157248u);  // 34³ x 4 B in 64-byte rows
  EXPECT_FALSE(no_labels.has_labels());
  EXPECT_TRUE(no_labels.slot_labels(0).empty());
  EXPECT_EQ(no_labels.slot_voxels(0).size(), 39304u);
}

TEST(BrickCache, BudgetTooSmallIsAnInputError) {
  const BrickLayout layout = BrickLayout::make(ivec3(97, 131, 73), vec3(1.0f), 64);  // 3 levels, 2.4 MB slots
  try {
    BrickCache c(layout, VoxelType::F32, VoxelType::U32, 4);
    ADD_FAILURE() << "no throw";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "--cache-mb");
    EXPECT_NE(e.reason().find("at least one brick per level"), std::string::npos) << e.reason();
    EXPECT_NE(e.reason().find("use at least 7"), std::string::npos) << e.reason();
  }
  EXPECT_NO_THROW(BrickCache(layout, VoxelType::F32, VoxelType::U32, 7));
}

TEST(BrickCache, LruOrderAndEviction) {
  const BrickLayout layout = BrickLayout::make(ivec3(97, 131, 73), vec3(1.0f), 32);
  BrickCache c(layout, VoxelType::U8, VoxelType::U32, 1);  // 5 slots
  const BrickCacheView v = c.view();
  // Fill: brick k loaded in frame k + 1.
  std::uint32_t slot_of[5];
  for (int k = 0; k < 5; ++k) {
    const auto a = c.allocate(brick(k), std::uint32_t(k + 1));
    ASSERT_TRUE(a.has_value());
    EXPECT_FALSE(a->evicted.valid());  // free slots first
    slot_of[k] = a->slot;
  }
  EXPECT_EQ(c.resident_count(), 5u);
  // The caster uses bricks 0 and 2 in frame 6, brick 3 in frame 7.
  v.touch(slot_of[0], 6);
  v.touch(slot_of[2], 6);
  v.touch(slot_of[3], 7);
  EXPECT_EQ(c.last_used(slot_of[3]), 7u);
  // Stamps now: b0 6, b1 2, b2 6, b3 7, b4 5 -> eviction order b1, b4, b0, b2 (tie: lower slot).
  const BrickId order[] = {brick(1), brick(4), slot_of[0] < slot_of[2] ? brick(0) : brick(2),
                           slot_of[0] < slot_of[2] ? brick(2) : brick(0)};
  for (int k = 0; k < 4; ++k) {
    const auto a = c.allocate(brick(10 + k), 8);
    ASSERT_TRUE(a.has_value());
    EXPECT_EQ(a->evicted, order[k]) << k;
    EXPECT_EQ(c.brick_in(a->slot), brick(10 + k));
    EXPECT_EQ(c.last_used(a->slot), 8u);  // stamped: a batch does not evict itself
  }
  EXPECT_EQ(c.evictions(), 4u);
  // Only brick 3 (frame 7) is older than frame 8 now.
  const auto a = c.allocate(brick(20), 8);
  ASSERT_TRUE(a.has_value());
  EXPECT_EQ(a->evicted, brick(3));
  // Everything is in use in frame 8: nothing to evict.
  EXPECT_FALSE(c.allocate(brick(21), 8).has_value());
  // A freed slot is used before any eviction, even when older slots exist.
  c.release(a->slot);
  const auto b = c.allocate(brick(22), 9);
  ASSERT_TRUE(b.has_value());
  EXPECT_FALSE(b->evicted.valid());
  EXPECT_EQ(b->slot, a->slot);
}

TEST(BrickCache, NeverEvictsSlotsUsedThisFrameWhileOthersAreFree) {
  const BrickLayout layout = BrickLayout::make(ivec3(97, 131, 73), vec3(1.0f), 32);
  BrickCache c(layout, VoxelType::U8, VoxelType::U32, 1);  // 5 slots
  const BrickCacheView v = c.view();
  for (int k = 0; k < 3; ++k) v.touch(c.allocate(brick(k), 4)->slot, 4);
  for (int k = 3; k < 5; ++k) {
    const auto a = c.allocate(brick(k), 4);
    ASSERT_TRUE(a.has_value());
    EXPECT_FALSE(a->evicted.valid());
  }
  EXPECT_FALSE(c.allocate(brick(5), 4).has_value());
  const auto a = c.allocate(brick(5), 5);  // next frame: the oldest (all frame 4, lowest slot) goes
  ASSERT_TRUE(a.has_value());
  EXPECT_TRUE(a->evicted.valid());
}

// Many caster threads stamping usage at once (run under TSan: atomic_ref, no data race). Within a
// real frame all threads write the same frame number; here they race with different ones, so only
// the range of the result is known.
TEST(BrickCache, ConcurrentTouch) {
  const BrickLayout layout = BrickLayout::make(ivec3(64), vec3(1.0f), 8);
  BrickCache c(layout, VoxelType::U8, std::nullopt, 1);
  for (int k = 0; k < 8; ++k) c.allocate(BrickId::pack(0, {k, 0, 0}), 1);
  const BrickCacheView v = c.view();
  std::vector<std::thread> threads;
  for (int t = 0; t < 8; ++t) {
    threads.emplace_back([&, t] {
      for (std::uint32_t f = 2; f < 2000; ++f) v.touch(std::uint32_t((t + f) % 8), f);
    });
  }
  for (std::thread& t : threads) t.join();
  for (std::uint32_t s = 0; s < 8; ++s) {
    EXPECT_GE(c.last_used(s), 2u);
    EXPECT_LT(c.last_used(s), 2000u);
  }
}

}  // namespace
}  // namespace sl
