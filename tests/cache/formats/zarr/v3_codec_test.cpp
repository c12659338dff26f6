// Zarr v3 codec chains and shard reads without a peer: the crc32c check value, the byte ranges a
// sharded read asks its ByteStore for (index once, then only the inner chunk wanted), empty inner
// chunks, and the chains the reader refuses with a reason.
#include "cache/formats/zarr/v3_chunk.h"

#include <gtest/gtest.h>

#include <map>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "cache/formats/zarr/array.h"
#include "cache/formats/zarr/v3_array.h"

namespace sl::zarr::v3 {
namespace {

using json = nlohmann::json;

// Objects in memory; records every request.
class MemoryByteStore final : public ByteStore {
 public:
  std::map<std::string, std::vector<std::byte>> objects;
  mutable std::vector<std::string> requests;

  std::optional<std::vector<std::byte>> read(const std::string& key, std::uint64_t) const override {
    requests.push_back("all " + key);
    const auto it = objects.find(key);
    if (it == objects.end()) return std::nullopt;
    return it->second;
  }
  std::optional<std::vector<std::byte>> read_range(const std::string& key, std::uint64_t offset,
                                                   std::uint64_t n) const override {
    requests.push_back("range " + key + " " + std::to_string(offset) + "+" + std::to_string(n));
    const auto it = objects.find(key);
    if (it == objects.end()) return std::nullopt;
    if (offset + n > it->second.size()) throw std::runtime_error("past the end");
    return std::vector<std::byte>(it->second.begin() + long(offset), it->second.begin() + long(offset + n));
  }
  std::optional<std::vector<std::byte>> read_suffix(const std::string& key, std::uint64_t n) const override {
    requests.push_back("suffix " + key + " " + std::to_string(n));
    const auto it = objects.find(key);
    if (it == objects.end()) return std::nullopt;
    return std::vector<std::byte>(it->second.end() - long(n), it->second.end());
  }
};

json sharded_array(const json& index_codecs) {
  return {{"zarr_format", 3},
          {"node_type", "array"},
          {"shape", {4, 4, 8}},
          {"data_type", "uint8"},
          {"chunk_grid", {{"name", "regular"}, {"configuration", {{"chunk_shape", {4, 4, 8}}}}}},
          {"chunk_key_encoding", {{"name", "default"}}},
          {"fill_value", 3},
          {"codecs",
           {{{"name", "sharding_indexed"},
             {"configuration",
              {{"chunk_shape", {4, 4, 4}},
               {"codecs", {{{"name", "bytes"}}}},
               {"index_codecs", index_codecs},
               {"index_location", "end"}}}}}}};
}

void put_u64(std::vector<std::byte>& b, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) b.push_back(std::byte((v >> (8 * i)) & 0xFF));
}

TEST(Zarr3Codec, Crc32cCheckValue) {
  const std::string s = "123456789";
  EXPECT_EQ(crc32c(reinterpret_cast<const std::byte*>(s.data()), s.size()), 0xE3069283u);
}

TEST(Zarr3Codec, ShardReadsTheIndexOnceThenOnlyTheInnerChunkWanted) {
  const ArrayMeta m = parse_array(sharded_array({{{"name", "bytes"}, {"configuration", {{"endian", "little"}}}},
                                                 {{"name", "crc32c"}}}));
  ASSERT_TRUE(m.v3 && m.v3->shard);
  EXPECT_EQ(m.chunks, (std::vector<std::int64_t>{4, 4, 4}));  // the read grid is the inner chunks
  EXPECT_EQ(m.v3->shard->index_bytes, 2u * 16u + 4u);        // two inner chunks, then the checksum
  // Inner chunk 1 holds 64 voxels of 9 at offset 0; inner chunk 0 is empty.
  std::vector<std::byte> shard(64, std::byte(9)), index;
  put_u64(index, ~0ull);
  put_u64(index, ~0ull);
  put_u64(index, 0);
  put_u64(index, 64);
  const std::uint32_t crc = crc32c(index.data(), index.size());
  for (int i = 0; i < 4; ++i) index.push_back(std::byte((crc >> (8 * i)) & 0xFF));
  shard.insert(shard.end(), index.begin(), index.end());
  MemoryByteStore store;
  store.objects["0/c/0/0/0"] = shard;
  ChunkCache cache(1 << 20);

  const auto one = read_chunk(*m.v3, store, "0/", {0, 0, 1}, cache, "s");
  ASSERT_TRUE(one);
  EXPECT_EQ(*one, std::vector<std::byte>(64, std::byte(9)));
  EXPECT_EQ(store.requests, (std::vector<std::string>{"suffix 0/c/0/0/0 36", "range 0/c/0/0/0 0+64"}));
  store.requests.clear();
  EXPECT_FALSE(read_chunk(*m.v3, store, "0/", {0, 0, 0}, cache, "s"));  // empty: the fill value, no read
  EXPECT_TRUE(store.requests.empty());
  EXPECT_FALSE(read_chunk(*m.v3, store, "0/", {0, 1, 0}, cache, "s"));  // no such shard
  EXPECT_EQ(store.requests, (std::vector<std::string>{"suffix 0/c/0/1/0 36"}));

  store.objects["0/c/0/0/0"][70] ^= std::byte(1);  // inside the index
  ChunkCache fresh(1 << 20);
  try {
    read_chunk(*m.v3, store, "0/", {0, 0, 1}, fresh, "s");
    FAIL() << "corrupt index read";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("shard 'c/0/0/0' inner chunk (0,0,1): shard index crc32c checksum mismatch"),
              std::string::npos)
        << e.what();
  }
}

void expect_refused(json j, const std::string& why) {
  try {
    parse_array(j);
    ADD_FAILURE() << "accepted: " << j.dump();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(why), std::string::npos) << e.what();
  }
}

TEST(Zarr3Codec, RefusesWhatItCannotDecode) {
  const json idx = {{{"name", "bytes"}, {"configuration", {{"endian", "little"}}}}};
  json j = sharded_array(idx);
  j["data_type"] = "int64";
  expect_refused(j, "data_type 'int64' is not supported");
  j = sharded_array({{{"name", "bytes"}, {"configuration", {{"endian", "little"}}}}, {{"name", "gzip"}}});
  expect_refused(j, "shard index codecs must have a fixed size");
  j = sharded_array(idx);
  j["codecs"][0]["configuration"]["chunk_shape"] = {4, 4, 3};
  expect_refused(j, "does not divide the shard shape 4x4x8");
  j = sharded_array(idx);
  j["codecs"][0]["configuration"]["codecs"] = j["codecs"];
  expect_refused(j, "nested sharding_indexed is not supported");
  j = sharded_array(idx);
  j["data_type"] = "uint16";
  expect_refused(j, "bytes codec needs an \"endian\"");
  j = sharded_array(idx);
  j["codecs"] = {{{"name", "bytes"}}, {{"name", "gzip"}}, {{"name", "zstd"}}};
  expect_refused(j, "two compressors in one chain");
  j["codecs"] = {{{"name", "bytes"}}, {{"name", "lzma"}}};
  expect_refused(j, "codec 'lzma' is not supported");
  j["codecs"] = {{{"name", "crc32c"}}, {{"name", "bytes"}}};
  expect_refused(j, "crc32c before the array->bytes codec");
  j["codecs"] = {{{"name", "bytes"}}};
  j["chunk_key_encoding"] = {{"name", "v3"}};
  expect_refused(j, "chunk_key_encoding must be named");
  j["chunk_key_encoding"] = {{"name", 5}};
  expect_refused(j, "unexpected JSON type (type must be string, but is number)");
  j["chunk_key_encoding"] = {{"name", "v2"}};
  j["node_type"] = json::array();
  expect_refused(j, "unexpected JSON type");
  j["node_type"] = "array";
  j["fill_value"] = "NaN";
  expect_refused(j, "fill_value \"NaN\" is not a number of the data type");
}

// Shapes, chunk and shard sizes whose products or rounding-up divisions wrap 64 bits (or come near it)
// are refused with the quantity named, never read as a small or empty grid.
TEST(Zarr3Codec, SizeArithmeticIsCheckedNotWrapped) {
  const json idx = {{{"name", "bytes"}, {"configuration", {{"endian", "little"}}}}};
  const std::int64_t big = 2147483647;
  // Five axes with the leading shard sizes at 2^31 - 1 and inner chunks of 1: 2^124 inner chunks per shard.
  json j = sharded_array(idx);
  j["shape"] = {1, 1, 4, 4, 8};
  j["chunk_grid"]["configuration"]["chunk_shape"] = {big, big, 4, 4, 8};
  j["codecs"][0]["configuration"]["chunk_shape"] = {1, 1, 4, 4, 4};
  expect_refused(j, "overflows 64-bit arithmetic");
  // Four axes: 2^62 inner chunks per shard fits 64 bits but not the shard index bound.
  j["shape"] = {1, 4, 4, 8};
  j["chunk_grid"]["configuration"]["chunk_shape"] = {big, 4, 4, 8};
  j["codecs"][0]["configuration"]["chunk_shape"] = {1, 4, 4, 4};
  expect_refused(j, "shard index of");
  // A shard of 2^36 inner chunks: a 1 TiB index, refused before anything is read.
  j = sharded_array(idx);
  j["shape"] = {4096, 4096, 4096};
  j["chunk_grid"]["configuration"]["chunk_shape"] = {4096, 4096, 4096};
  j["codecs"][0]["configuration"]["chunk_shape"] = {1, 1, 1};
  expect_refused(j, "shard index of 1099511627776 bytes");
  // 2^22 + some inner chunks: an index within the byte bound but over the inner-chunk limit.
  j["chunk_grid"]["configuration"]["chunk_shape"] = {2048, 2048, 2};
  j["shape"] = {2048, 2048, 2};
  j["codecs"][0]["configuration"]["chunk_shape"] = {1, 1, 1};
  expect_refused(j, "shard index of");
  // Unsharded chunks of (2^31 - 1)^3 elements: the decoded size wraps.
  j = sharded_array(idx);
  j["codecs"] = {{{"name", "bytes"}}};
  j["chunk_grid"]["configuration"]["chunk_shape"] = {big, big, big};
  expect_refused(j, "overflows 64-bit arithmetic");
  // Chunks of 1 over a (2^31 - 1)^3 shape: a chunk grid of 2^93.
  j["shape"] = {big, big, big};
  j["chunk_grid"]["configuration"]["chunk_shape"] = {1, 1, 1};
  expect_refused(j, "chunk grid (2147483647 x 2147483647 x 2147483647) overflows 64-bit arithmetic");
  // Sharded: the shard grid.
  j = sharded_array(idx);
  j["shape"] = {big, big, big};
  j["chunk_grid"]["configuration"]["chunk_shape"] = {1, 1, 2};
  j["codecs"][0]["configuration"]["chunk_shape"] = {1, 1, 1};
  expect_refused(j, "shard grid (2147483647 x 2147483647 x 1073741824) overflows 64-bit arithmetic");
  // Decoded chunks past 1 GiB, without wrapping.
  j = sharded_array(idx);
  j["codecs"] = {{{"name", "bytes"}}};
  j["data_type"] = "uint8";
  j["chunk_grid"]["configuration"]["chunk_shape"] = {2048, 2048, 512};
  expect_refused(j, "exceed the 1 GiB limit");
}

TEST(Zarr3Codec, ChunkKeys) {
  ArrayCodecs a;
  EXPECT_EQ(a.key({0, 1, 2}), "c/0/1/2");
  a.separator = '.';
  EXPECT_EQ(a.key({0, 1, 2}), "c.0.1.2");
  a.default_keys = false;
  EXPECT_EQ(a.key({0, 1, 2}), "0.1.2");
  a.separator = '/';
  EXPECT_EQ(a.key({3, 0, 12}), "3/0/12");
}

}  // namespace
}  // namespace sl::zarr::v3
