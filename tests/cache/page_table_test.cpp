#include "cache/page_table.h"

#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include <cstdio>
#include <algorithm>
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

TEST(PageTable, ChunksAllocatedOnTouchAndReleased) {
  const BrickLayout l = BrickLayout::make(ivec3(4096, 4096, 4096), vec3(1.0f), 32);  // 128³ bricks
  PageTable pt(l);
  const std::size_t base = pt.memory_bytes();
  EXPECT_EQ(pt.live_chunks(), 0u);
  // Two bricks in one leaf chunk (4³ bricks): one node chunk + one leaf chunk.
  pt.set(BrickId::pack(0, {0, 0, 0}), PageEntry::empty());
  pt.set(BrickId::pack(0, {3, 3, 3}), PageEntry::resident(7));
  EXPECT_EQ(pt.live_chunks(), 2u);
  // Same directory word (16³ bricks), another leaf chunk: one more chunk.
  pt.set(BrickId::pack(0, {15, 15, 15}), PageEntry::resident(8));
  EXPECT_EQ(pt.live_chunks(), 3u);
  // Another directory word: node + leaf.
  pt.set(BrickId::pack(0, {16, 0, 0}), PageEntry::resident(9));
  EXPECT_EQ(pt.live_chunks(), 5u);
  // Neighbouring entries of a touched chunk are still Unmapped; untouched regions too.
  EXPECT_EQ(pt.get(BrickId::pack(0, {1, 0, 0})).state(), PageEntry::State::Unmapped);
  EXPECT_EQ(pt.get(BrickId::pack(0, {4, 0, 0})).state(), PageEntry::State::Unmapped);
  EXPECT_EQ(pt.get(BrickId::pack(0, {100, 100, 100})).state(), PageEntry::State::Unmapped);
  EXPECT_EQ(pt.get(BrickId::pack(3, {1, 1, 1})).state(), PageEntry::State::Unmapped);
  EXPECT_EQ(pt.get(BrickId::pack(0, {15, 15, 15})).slot(), 8u);
  // Clearing an entry of a region never touched allocates nothing.
  pt.clear(BrickId::pack(0, {100, 100, 100}));
  pt.clear(BrickId::pack(0, {1, 0, 0}));
  EXPECT_EQ(pt.live_chunks(), 5u);
  pt.clear(BrickId::pack(0, {16, 0, 0}));
  EXPECT_EQ(pt.live_chunks(), 3u);  // its leaf and node chunks held nothing else: both freed
  pt.clear(BrickId::pack(0, {15, 15, 15}));
  EXPECT_EQ(pt.live_chunks(), 2u);  // the leaf freed, the node still holds the first leaf
  pt.set(BrickId::pack(2, {5, 5, 5}), PageEntry::resident(10));  // reuses freed chunks
  EXPECT_EQ(pt.live_chunks(), 4u);
  EXPECT_EQ(pt.get(BrickId::pack(2, {5, 5, 5})).slot(), 10u);
  EXPECT_EQ(pt.get(BrickId::pack(0, {16, 0, 0})).state(), PageEntry::State::Unmapped);
  EXPECT_EQ(pt.get(BrickId::pack(0, {3, 3, 3})).slot(), 7u);
  EXPECT_GT(pt.memory_bytes(), base);
  pt.reset();
  EXPECT_EQ(pt.live_chunks(), 0u);
  EXPECT_EQ(pt.mapped_entries(), 0u);
  EXPECT_EQ(pt.memory_bytes(), base);
  EXPECT_EQ(pt.get(BrickId::pack(0, {3, 3, 3})).state(), PageEntry::State::Unmapped);
}

// DESIGN.md "Virtual memory": a 30-million-brick level costs memory only where rays went.
TEST(PageTable, HugeLevelCostsOnlyTouchedChunks) {
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
  std::printf("[ page table ] 30.7 M-brick level, 100 bricks along a ray: %zu chunks, %.1f KB (empty table %.1f KB)\n",
              pt.live_chunks(), double(pt.memory_bytes()) / 1024.0, double(empty_bytes) / 1024.0);
  EXPECT_LT(pt.memory_bytes() - empty_bytes, 100u * 2u * kChunkWords * 4u);
}

// Issue 14: page-table memory proportional to the bricks touched. N bricks scattered so that no two
// share a directory word cost exactly 2 N chunks (256 bytes each) above the empty table — O(N), where
// 16³-brick pages cost 16 KB each — and unmapping them gives the memory back.
TEST(PageTable, ScatteredBricksCostLinearMemoryAndFreeingReturnsIt) {
  const BrickLayout l = BrickLayout::make(ivec3(10000, 10000, 10000), vec3(1.0f), 32);  // 313³ bricks
  PageTable pt(l);
  const std::size_t empty_bytes = pt.memory_bytes();
  std::vector<BrickId> ids;
  for (int i = 0; i < 100; ++i) ids.push_back(BrickId::pack(0, {(i * 37) % 313, (i * 91) % 313, (i * 53) % 313}));
  for (std::size_t n = 0; n < ids.size(); ++n) {
    pt.set(ids[n], PageEntry::empty());
    EXPECT_EQ(pt.live_chunks(), 2 * (n + 1));
  }
  const std::size_t words = pt.live_chunks() * kChunkWords;
  const std::size_t full = pt.memory_bytes();
  std::printf("[ page table ] 100 scattered bricks: %zu chunks, %.1f KB above the empty table (%.1f KB)\n",
              pt.live_chunks(), double(full - empty_bytes) / 1024.0, double(empty_bytes) / 1024.0);
  EXPECT_GE(full - empty_bytes, words * 4);
  EXPECT_LT(full - empty_bytes, 2 * words * 4 + 4096);  // vector growth at most doubles
  for (std::size_t n = 0; n < ids.size(); ++n) EXPECT_EQ(pt.get(ids[n]).state(), PageEntry::State::Empty);
  // Unmapped in an order unlike the one they were set in: every chunk is freed and the pool shrinks.
  for (std::size_t n = 0; n < ids.size(); n += 2) pt.clear(ids[n]);
  EXPECT_EQ(pt.live_chunks(), ids.size());
  for (std::size_t n = 1; n < ids.size(); n += 2) pt.clear(ids[n]);
  EXPECT_EQ(pt.live_chunks(), 0u);
  EXPECT_EQ(pt.mapped_entries(), 0u);
  EXPECT_LE(pt.memory_bytes(), empty_bytes + 64 * kChunkWords * 4);  // at most the slack kept for regrowth
  // And it can be touched again.
  pt.set(ids[5], PageEntry::resident(3));
  EXPECT_EQ(pt.get(ids[5]).slot(), 3u);
  EXPECT_EQ(pt.live_chunks(), 2u);
}

// The words a change reports are exactly the words whose value changed (what a device mirror needs):
// a mirror fed only those words reads every entry as the host does.
TEST(PageTable, ChangedWordsKeepAMirrorExact) {
  const BrickLayout l = BrickLayout::make(ivec3(700, 500, 300), vec3(1.0f), 8);
  PageTable pt(l);
  const PageTableView g = pt.view();
  std::size_t dir_words = 0;
  for (int k = 0; k < l.levels; ++k) {
    dir_words = std::max<std::size_t>(dir_words, g.level[k].directory_offset + std::size_t(g.level[k].pages.x) *
                                                                                 g.level[k].pages.y * g.level[k].pages.z);
  }
  std::vector<std::uint32_t> dir(dir_words, 0u), pool;
  std::uint64_t seed = 12345;
  auto next = [&seed](int n) {
    seed = seed * 6364136223846793005ull + 1442695040888963407ull;
    return int((seed >> 33) % std::uint64_t(n));
  };
  std::vector<BrickId> touched;
  for (int i = 0; i < 4000; ++i) {
    BrickId id;
    if (!touched.empty() && next(3) == 0) {
      id = touched[std::size_t(next(int(touched.size())))];
    } else {
      const int level = next(2);
      const ivec3 n = l.bricks(level);
      id = BrickId::pack(level, {next(n.x), next(n.y), next(n.z)});
      touched.push_back(id);
    }
    const PageEntry e = next(2) ? PageEntry::unmapped() : PageEntry::resident(std::uint32_t(i));
    PageTableUpdate u;
    pt.set(id, e, &u);
    for (std::uint32_t di : u.dir_index) u.dir_value.push_back(pt.directory_word(di));
    for (std::uint64_t pi : u.pool_index) u.pool_value.push_back(pt.pool_word(pi));
    if (u.pool_words_needed() > pool.size()) pool.resize(std::size_t(u.pool_words_needed()), 0u);
    for (std::size_t k = 0; k < u.dir_index.size(); ++k) dir[u.dir_index[k]] = u.dir_value[k];
    for (std::size_t k = 0; k < u.pool_index.size(); ++k) pool[std::size_t(u.pool_index[k])] = u.pool_value[k];
    PageTableView m = pt.view();
    m.directory = dir.data();
    m.pool = pool.data();
    ASSERT_EQ(m.lookup(id), pt.get(id)) << "op " << i;
  }
  PageTableView m = pt.view();
  m.directory = dir.data();
  m.pool = pool.data();
  for (const BrickId id : touched) ASSERT_EQ(m.lookup(id), pt.get(id));
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
