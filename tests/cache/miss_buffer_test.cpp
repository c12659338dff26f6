#include "cache/miss_buffer.h"

#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include <algorithm>
#include <set>
#include <thread>
#include <vector>

namespace sl {
namespace {

BrickId id_of(int i) { return BrickId::pack(i % 3, {i, 2 * i + 1, i / 2}); }

// Many rays hit one brick: 8 threads x 100k inserts of 50 distinct ids -> exactly 50.
TEST(MissBuffer, DeduplicatesAcrossThreads) {
  MissBuffer mb(1024);
  const MissBufferView v = mb.view();
  std::vector<std::thread> threads;
  std::vector<int> added(8, 0);
  for (int t = 0; t < 8; ++t) {
    threads.emplace_back([&, t] {
      for (int i = 0; i < 100000; ++i) added[std::size_t(t)] += v.insert(id_of((i * 7 + t * 13) % 50)) ? 1 : 0;
    });
  }
  for (std::thread& t : threads) t.join();
  int total_added = 0;
  for (const int a : added) total_added += a;
  EXPECT_EQ(total_added, 50);  // each id was appended by exactly one insert
  EXPECT_EQ(mb.size(), 50u);
  EXPECT_EQ(mb.dropped(), 0u);
  std::vector<BrickId> want;
  for (int i = 0; i < 50; ++i) want.push_back(id_of(i));
  std::sort(want.begin(), want.end());
  EXPECT_EQ(mb.drain(), want);  // sorted, de-duplicated
}

TEST(MissBuffer, OverflowIsCountedAndClearResets) {
  MissBuffer mb(10);
  const MissBufferView v = mb.view();
  for (int i = 0; i < 25; ++i) v.insert(id_of(i));
  EXPECT_EQ(mb.size(), 10u);
  EXPECT_EQ(mb.dropped(), 15u);
  EXPECT_TRUE(mb.overflowed());
  // Ids already listed are duplicates, not drops.
  const std::vector<BrickId> listed = mb.drain();
  for (const BrickId id : listed) EXPECT_FALSE(v.insert(id));
  EXPECT_EQ(mb.dropped(), 15u);
  mb.clear();
  EXPECT_EQ(mb.size(), 0u);
  EXPECT_EQ(mb.dropped(), 0u);
  EXPECT_TRUE(mb.drain().empty());
  EXPECT_TRUE(v.insert(id_of(3)));  // the view stays valid across clear()
  EXPECT_EQ(mb.drain(), std::vector<BrickId>{id_of(3)});
}

TEST(MissBuffer, ManyThreadsOverflowCountsEveryLostInsert) {
  MissBuffer mb(100);
  const MissBufferView v = mb.view();
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&, t] {
      for (int i = 0; i < 1000; ++i) v.insert(BrickId::pack(0, {t * 1000 + i, 0, 0}));
    });
  }
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(mb.size(), 100u);
  // 4000 distinct ids, 100 listed; the table holds 256 slots, so every other insert was lost,
  // counted once each (the 156 claimed-but-unlisted ids) or per attempt (table full).
  EXPECT_EQ(mb.dropped(), 3900u);
  const std::vector<BrickId> ids = mb.drain();
  EXPECT_EQ(std::set<BrickId>(ids.begin(), ids.end()).size(), 100u);
  mb.clear();  // the full-table clear path
  for (int i = 0; i < 100; ++i) EXPECT_TRUE(v.insert(BrickId::pack(0, {i, 0, 0})));
  EXPECT_EQ(mb.dropped(), 0u);
}

RC_GTEST_PROP(MissBuffer, DrainIsTheSortedSetOfInserts, ()) {
  const auto raw = *rc::gen::container<std::vector<std::uint32_t>>(rc::gen::inRange<std::uint32_t>(0, 300));
  MissBuffer mb(512);
  std::set<BrickId> want;
  for (int round = 0; round < 2; ++round) {  // clear() must leave a table as good as new
    const MissBufferView v = mb.view();
    want.clear();
    for (const std::uint32_t r : raw) {
      const BrickId id = BrickId::pack(int(r % 4), {int(r), int(r * 3 % 17), round});
      const bool fresh = want.insert(id).second;
      RC_ASSERT(v.insert(id) == fresh);
    }
    const std::vector<BrickId> got = mb.drain();
    RC_ASSERT(got == std::vector<BrickId>(want.begin(), want.end()));
    RC_ASSERT(mb.dropped() == 0u);
    mb.clear();
  }
}

}  // namespace
}  // namespace sl
