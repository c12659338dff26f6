// The sharded format's addressing (cache/formats/precomputed/shard.h) on values worked out by hand:
// compressed Morton codes (including the worked example in the VNC shard-debugging notes: chunk
// (335, 438, 1024) of a 671 x 877 x 1286 grid is 0x434522d9), shard file names and minishard/shard bits,
// and index decoding.
// tensorstore-written shards (interop_test.cpp) check the hash and the whole read.
#include <gtest/gtest.h>

#include <stdexcept>

#include "cache/formats/precomputed/shard.h"

namespace sl::precomputed {
namespace {

TEST(PrecomputedShard, CompressedMortonCode) {
  EXPECT_EQ(compressed_morton_code(ivec3(0), ivec3(1)), 0u);
  // Equal bits per axis: plain x, y, z interleaving from the least significant bit.
  EXPECT_EQ(compressed_morton_code(ivec3(1, 0, 0), ivec3(4)), 1u);
  EXPECT_EQ(compressed_morton_code(ivec3(0, 1, 0), ivec3(4)), 2u);
  EXPECT_EQ(compressed_morton_code(ivec3(0, 0, 1), ivec3(4)), 4u);
  EXPECT_EQ(compressed_morton_code(ivec3(3, 3, 3), ivec3(4)), 63u);
  // An axis of one chunk takes no bits; x of 2 chunks takes one, y of 8 three.
  EXPECT_EQ(compressed_morton_code(ivec3(1, 7, 0), ivec3(2, 8, 1)), 0b1111u);
  EXPECT_EQ(compressed_morton_code(ivec3(0, 4, 0), ivec3(2, 8, 1)), 0b1000u);
  EXPECT_EQ(compressed_morton_code(ivec3(335, 438, 1024), ivec3(671, 877, 1286)), 0x434522d9u);
}

TEST(PrecomputedShard, LocateChunk) {
  Sharding s;
  s.preshift_bits = 9;
  s.minishard_bits = 6;
  s.shard_bits = 16;
  // The same worked example: identity hash, shard 0x868a, minishard 0x11.
  const ShardLocation loc = locate_chunk(s, 0x434522d9u);
  EXPECT_EQ(loc.file, "868a.shard");
  EXPECT_EQ(loc.minishard, 0x11u);
  s.shard_bits = 0;
  EXPECT_EQ(locate_chunk(s, 0x434522d9u).file, "0.shard");
  s.shard_bits = 5;  // two hex digits, zero padded
  EXPECT_EQ(locate_chunk(s, std::uint64_t(3) << 15).file, "03.shard");
  s.murmur_hash = true;
  EXPECT_EQ(locate_chunk(s, 5).minishard, murmurhash3_x86_128_low64(0) & 63u);  // 5 >> 9 = 0
  EXPECT_NE(murmurhash3_x86_128_low64(0), murmurhash3_x86_128_low64(1));
}

TEST(PrecomputedShard, IndexDecoding) {
  Sharding s;
  s.minishard_bits = 1;  // 32-byte shard index
  std::vector<std::byte> e(16);
  e[0] = std::byte{10};
  e[8] = std::byte{58};
  const ByteRange r = decode_shard_index_entry(s, e);
  EXPECT_EQ(r.start, 42u);
  EXPECT_EQ(r.end, 90u);
  // Two chunks: ids 3 and 3 + 4, offsets 5 and 5 + 100 + 2 (after the first chunk's 100 bytes), sizes 100, 7.
  std::vector<std::byte> m;
  for (std::uint64_t v : {3, 4, 5, 2, 100, 7}) {
    for (int i = 0; i < 8; ++i) m.push_back(std::byte((v >> (8 * i)) & 0xff));
  }
  const std::vector<MinishardEntry> d = decode_minishard_index(s, m, ByteRange{500, 548});
  ASSERT_EQ(d.size(), 2u);
  EXPECT_EQ(d[0].chunk_id, 3u);
  EXPECT_EQ(d[0].offset, 32u + 5u);
  EXPECT_EQ(d[0].size, 100u);
  EXPECT_EQ(d[1].chunk_id, 7u);
  EXPECT_EQ(d[1].offset, 32u + 107u);
  EXPECT_EQ(d[1].size, 7u);
  // The same entries where the index itself lies inside the first chunk.
  EXPECT_THROW(decode_minishard_index(s, m, ByteRange{40, 88}), std::runtime_error);
}

}  // namespace
}  // namespace sl::precomputed
