// The bounded block-metadata cache of the out-of-core renderer: least recently used blocks
// go first, blocks of the last two frames never, and the memory it reports follows what it holds.
#include "cache/metadata_cache.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <set>

#include <rapidcheck/gtest.h>

namespace sl {
namespace {

BlockMetadata with_labels(std::size_t n) {
  BlockMetadata m;
  m.computed = true;
  m.has_labels = n > 0;
  for (std::size_t i = 0; i < n; ++i) m.labels.push_back(std::uint32_t(i));
  return m;
}

TEST(MetadataCache, EvictsTheLeastRecentlyUsedDownToSevenEighths) {
  MetadataCache c(16);
  for (std::uint64_t k = 0; k < 20; ++k) c.put(k, with_labels(1), std::uint32_t(k + 1));  // k used at frame k + 1
  c.touch(0, 30);  // the oldest, used again
  const std::vector<std::uint64_t> dropped = c.evict(30);
  // 20 - 14 = 6 dropped: the six least recently used, 1..6 (0 was touched at frame 30).
  EXPECT_EQ(std::set<std::uint64_t>(dropped.begin(), dropped.end()), (std::set<std::uint64_t>{1, 2, 3, 4, 5, 6}));
  EXPECT_EQ(c.size(), 14u);
  EXPECT_TRUE(c.contains(0));
  EXPECT_FALSE(c.contains(1));
  EXPECT_EQ(c.evictions(), 6u);
  EXPECT_TRUE(c.evict(31).empty()) << "within the capacity nothing more goes";
}

TEST(MetadataCache, NeverDropsWhatTheLastTwoFramesUsed) {
  MetadataCache c(4);
  for (std::uint64_t k = 0; k < 10; ++k) c.put(k, with_labels(0), k < 8 ? 9 : 3);
  // Frame 10: blocks used at 9 (= frame - 1) stay; only 8 and 9 (used at 3) may go.
  const std::vector<std::uint64_t> dropped = c.evict(10);
  EXPECT_EQ(std::set<std::uint64_t>(dropped.begin(), dropped.end()), (std::set<std::uint64_t>{8, 9}));
  EXPECT_EQ(c.size(), 8u) << "a soft bound: a view needing more keeps what it uses";
}

TEST(MetadataCache, FindMarksUsedPeekDoesNot) {
  MetadataCache c(1);
  c.put(1, with_labels(0), 1);
  c.put(2, with_labels(0), 1);
  c.put(3, with_labels(0), 1);
  ASSERT_NE(c.find(1, 8), nullptr);
  (void)c.peek(2);
  EXPECT_EQ(c.find(99, 8), nullptr);
  const std::vector<std::uint64_t> dropped = c.evict(10);
  EXPECT_EQ(std::set<std::uint64_t>(dropped.begin(), dropped.end()), (std::set<std::uint64_t>{2, 3}));
}

TEST(MetadataCache, MemoryFollowsEntriesAndLabelLists) {
  MetadataCache c(1000);
  const std::size_t empty = c.memory_bytes();
  c.put(1, with_labels(1000), 1);
  const std::size_t one = c.memory_bytes();
  EXPECT_GE(one - empty, 1000 * sizeof(std::uint32_t));
  c.put(1, with_labels(10), 2);  // replaced: its old list no longer counts
  EXPECT_LT(c.memory_bytes(), one - 900 * sizeof(std::uint32_t));
}

// For any sequence of puts, touches and evictions: the cache never holds more than its capacity
// plus the blocks of the last two frames; what an eviction drops is never more recently used than
// what it keeps (apart from the protected recent blocks); and the memory estimate's label count is
// that of the lists held.
RC_GTEST_PROP(MetadataCache, EvictionKeepsTheMostRecentlyUsedWithinTheBound, ()) {
  const std::size_t capacity = *rc::gen::inRange<std::size_t>(1, 40);
  MetadataCache c(capacity);
  std::map<std::uint64_t, std::pair<std::uint32_t, std::size_t>> model;  // key -> (last use, labels)
  std::uint32_t frame = 1;
  const int steps = *rc::gen::inRange(1, 300);
  for (int i = 0; i < steps; ++i) {
    const int op = *rc::gen::inRange(0, 10);
    const std::uint64_t key = *rc::gen::inRange<std::uint64_t>(0, 80);
    if (op < 5) {
      const std::size_t n = *rc::gen::inRange<std::size_t>(0, 5);
      c.put(key, with_labels(n), frame);
      auto& e = model[key];
      e.first = std::max(e.first, frame);
      e.second = n;
    } else if (op < 7) {
      c.touch(key, frame);
      if (model.count(key)) model[key].first = std::max(model[key].first, frame);
    } else if (op < 9) {
      ++frame;
    } else {
      const std::vector<std::uint64_t> dropped = c.evict(frame);
      std::uint32_t newest_dropped = 0;
      for (const std::uint64_t k : dropped) {
        RC_ASSERT(model.count(k) == 1u);
        RC_ASSERT(model[k].first + 1 < frame);  // never a block of the last two frames
        newest_dropped = std::max(newest_dropped, model[k].first);
        model.erase(k);
      }
      std::size_t recent = 0;
      for (const auto& [k, e] : model) {
        if (e.first + 1 >= frame) ++recent;
        if (!dropped.empty() && e.first + 1 < frame) RC_ASSERT(e.first >= newest_dropped);
      }
      RC_ASSERT(c.size() <= std::max(capacity, recent));
    }
    RC_ASSERT(c.size() == model.size());
  }
  for (const auto& [k, e] : model) {
    RC_ASSERT(c.contains(k));
    RC_ASSERT(c.peek(k).labels.size() == e.second);
  }
}

}  // namespace
}  // namespace sl
