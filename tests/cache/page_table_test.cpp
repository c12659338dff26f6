#include "cache/page_table.h"

#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include <cstdio>
#include <cstring>
#include <vector>

namespace sl {
namespace {

template <class Fn>
void for_each_brick(const BrickLayout& l, Fn fn) {
  for (int level = 0; level < l.levels; ++level) {
    const ivec3 n = l.bricks(level);
    for (int z = 0; z < n.z; ++z)
      for (int y = 0; y < n.y; ++y)
        for (int x = 0; x < n.x; ++x) fn(BrickId::pack(level, {x, y, z}));
  }
}

TEST(PageEntry, Encoding) {
  EXPECT_EQ(PageEntry{}.state(), PageEntry::State::Unmapped);
  EXPECT_EQ(PageEntry{}.bits, 0u);  // zeroed pages read Unmapped
  const PageEntry r = PageEntry::resident(123456);
  EXPECT_EQ(r.state(), PageEntry::State::Resident);
  EXPECT_EQ(r.slot(), 123456u);
  EXPECT_EQ(r.bits, (1u << 30) | 123456u);
  EXPECT_EQ(PageEntry::resident(PageEntry::kPayloadMask).slot(), PageEntry::kPayloadMask);
  EXPECT_EQ(PageEntry::empty().state(), PageEntry::State::Empty);
  EXPECT_EQ(PageEntry::empty().bits, 2u << 30);

  EXPECT_TRUE(constant_encodable(200.0f, VoxelType::U8));
  EXPECT_FALSE(constant_encodable(2.5f, VoxelType::U16));
  EXPECT_FALSE(constant_encodable(-1.0f, VoxelType::U16));
  const PageEntry c = constant_entry(65535.0f, VoxelType::U16);
  EXPECT_EQ(c.state(), PageEntry::State::Constant);
  EXPECT_EQ(c.constant_value(VoxelType::U16), 65535.0f);
  for (const float f : {0.0f, 0.5f, -3.25f, 1.0e20f}) {  // two low mantissa bits zero: exact
    ASSERT_TRUE(constant_encodable(f, VoxelType::F32)) << f;
    EXPECT_EQ(constant_entry(f, VoxelType::F32).constant_value(VoxelType::F32), f);
  }
  EXPECT_FALSE(constant_encodable(0.1f, VoxelType::F32));  // 0.1f's mantissa ends in ...01
}

// Every brick of every level of odd-sized volumes: set, read back through the host API and the
// plain view, clear half, read again.
TEST(PageTable, TranslationAtEveryLevelOddDims) {
  for (const int b : {8, 32}) {
    for (const ivec3 dims : {ivec3(97, 131, 73), ivec3(1000, 17, 300)}) {
      SCOPED_TRACE(testing::Message() << "B=" << b << " dims " << dims.x << "x" << dims.y << "x" << dims.z);
      const BrickLayout l = BrickLayout::make(dims, vec3(1.0f), b);
      PageTable pt(l);
      std::uint32_t slot = 0;
      for_each_brick(l, [&](BrickId id) { EXPECT_EQ(pt.get(id).state(), PageEntry::State::Unmapped); });
      for_each_brick(l, [&](BrickId id) { pt.set(id, PageEntry::resident(slot++)); });
      const PageTableView v = pt.view();
      slot = 0;
      for_each_brick(l, [&](BrickId id) {
        const PageEntry e = v.lookup(id);
        ASSERT_TRUE(e.is_resident()) << to_string(id);
        ASSERT_EQ(e.slot(), slot++) << to_string(id);
        ASSERT_EQ(pt.get(id), e);
      });
      EXPECT_EQ(pt.mapped_entries(), slot);
      std::uint32_t k = 0;
      for_each_brick(l, [&](BrickId id) {
        if (k++ % 2) pt.clear(id);
      });
      k = 0;
      slot = 0;
      const PageTableView v2 = pt.view();
      for_each_brick(l, [&](BrickId id) {
        const PageEntry e = v2.lookup(id);
        if (k++ % 2) {
          ASSERT_EQ(e.state(), PageEntry::State::Unmapped);
        } else {
          ASSERT_EQ(e, PageEntry::resident(slot));
        }
        ++slot;
      });
      // Ids outside the layout read Unmapped through the view (no out-of-bounds read).
      EXPECT_EQ(v2.lookup(BrickId::pack(l.levels, {0, 0, 0})).state(), PageEntry::State::Unmapped);
      EXPECT_EQ(v2.lookup(BrickId::pack(0, l.bricks(0) + 16 * 4)).state(), PageEntry::State::Unmapped);
    }
  }
}

TEST(PageTable, PagesAllocatedOnTouchAndReleased) {
  const BrickLayout l = BrickLayout::make(ivec3(4096, 4096, 4096), vec3(1.0f), 32);  // 128³ bricks
  PageTable pt(l);
  const std::size_t base = pt.memory_bytes();
  EXPECT_EQ(pt.touched_pages(), 0u);
  // Two bricks in one page, one in another.
  pt.set(BrickId::pack(0, {0, 0, 0}), PageEntry::empty());
  pt.set(BrickId::pack(0, {15, 15, 15}), PageEntry::resident(7));
  EXPECT_EQ(pt.touched_pages(), 1u);
  pt.set(BrickId::pack(0, {16, 0, 0}), PageEntry::resident(8));
  EXPECT_EQ(pt.touched_pages(), 2u);
  // Neighbouring entries of a touched page are still Unmapped; untouched pages too.
  EXPECT_EQ(pt.get(BrickId::pack(0, {1, 0, 0})).state(), PageEntry::State::Unmapped);
  EXPECT_EQ(pt.get(BrickId::pack(0, {100, 100, 100})).state(), PageEntry::State::Unmapped);
  EXPECT_EQ(pt.get(BrickId::pack(3, {1, 1, 1})).state(), PageEntry::State::Unmapped);
  // Clearing an entry on a page never allocated allocates nothing.
  pt.clear(BrickId::pack(0, {100, 100, 100}));
  EXPECT_EQ(pt.touched_pages(), 2u);
  pt.clear(BrickId::pack(0, {16, 0, 0}));
  EXPECT_EQ(pt.touched_pages(), 1u);  // all-Unmapped page returned to the pool
  pt.set(BrickId::pack(2, {5, 5, 5}), PageEntry::resident(9));  // reuses the released page
  EXPECT_EQ(pt.touched_pages(), 2u);
  EXPECT_EQ(pt.get(BrickId::pack(2, {5, 5, 5})).slot(), 9u);
  EXPECT_EQ(pt.get(BrickId::pack(0, {16, 0, 0})).state(), PageEntry::State::Unmapped);
  EXPECT_GT(pt.memory_bytes(), base);
  pt.reset();
  EXPECT_EQ(pt.touched_pages(), 0u);
  EXPECT_EQ(pt.mapped_entries(), 0u);
  EXPECT_EQ(pt.get(BrickId::pack(0, {15, 15, 15})).state(), PageEntry::State::Unmapped);
}

// DESIGN.md §4: a 30-million-brick level costs memory only where rays went.
TEST(PageTable, HugeLevelCostsOnlyTouchedPages) {
  const BrickLayout l = BrickLayout::make(ivec3(10000, 10000, 10000), vec3(1.0f), 32);
  ASSERT_GT(l.brick_count(0), 30'000'000u);  // 313³ = 30.7 M bricks at level 0
  PageTable pt(l);
  const std::size_t empty_bytes = pt.memory_bytes();
  // 100 bricks along a ray through the volume, as a ray marching at level 0 would touch them.
  const vec3 a(100.0f, 9000.0f, 50.0f), d = glm::normalize(vec3(1.0f, -0.8f, 0.6f));
  int touched = 0;
  BrickId last;
  for (float t = 0.0f; touched < 100; t += 4.0f) {
    const BrickId id = l.brick_at(0, a + t * d);
    if (id == last) continue;
    last = id;
    pt.set(id, PageEntry::resident(std::uint32_t(touched++)));
  }
  const double kb = pt.memory_kb();
  std::printf("[ page table ] 30.7 M-brick level, 100 bricks along a ray: %zu pages, %.1f KB (empty table %.1f KB)\n",
              pt.touched_pages(), kb, double(empty_bytes) / 1024.0);
  EXPECT_LT(pt.memory_bytes(), std::size_t(1) << 20);

  // Worst case for the record: 100 bricks scattered so that each needs its own page (16 KB each).
  PageTable scattered(l);
  for (int i = 0; i < 100; ++i) scattered.set(BrickId::pack(0, {(i * 37) % 313, (i * 91) % 313, (i * 53) % 313}),
                                                PageEntry::empty());
  std::printf("[ page table ] 100 scattered bricks: %zu pages, %.1f KB\n", scattered.touched_pages(),
              scattered.memory_kb());
  EXPECT_LE(scattered.touched_pages(), 100u);
}

RC_GTEST_PROP(PageTable, MatchesAMap, ()) {
  const ivec3 dims(*rc::gen::inRange(1, 700), *rc::gen::inRange(1, 700), *rc::gen::inRange(1, 700));
  const BrickLayout l = BrickLayout::make(dims, vec3(1.0f), 8);
  PageTable pt(l);
  std::vector<std::pair<BrickId, PageEntry>> model;
  const int ops = *rc::gen::inRange(1, 200);
  for (int i = 0; i < ops; ++i) {
    const int level = *rc::gen::inRange(0, l.levels);
    const ivec3 n = l.bricks(level);
    const BrickId id = BrickId::pack(level, {*rc::gen::inRange(0, n.x), *rc::gen::inRange(0, n.y), *rc::gen::inRange(0, n.z)});
    const int kind = *rc::gen::inRange(0, 4);
    const PageEntry e = kind == 0 ? PageEntry::unmapped() : kind == 1 ? PageEntry::empty()
                                                                      : PageEntry::resident(std::uint32_t(i));
    pt.set(id, e);
    std::erase_if(model, [&](const auto& m) { return m.first == id; });
    if (kind != 0) model.emplace_back(id, e);
  }
  for (const auto& [id, e] : model) RC_ASSERT(pt.view().lookup(id) == e);
  RC_ASSERT(pt.mapped_entries() == model.size());
}

}  // namespace
}  // namespace sl
