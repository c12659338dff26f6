// Bad Neuroglancer precomputed input: malformed or unsupported `info` files, chunks of the wrong size,
// compressed_segmentation with bad offsets, shard indices and minishard indices that lie, ids too large
// for u32, and failures of the store itself. Each is one InputError naming the volume, the scale and the
// chunk (never a crash or a read of more than the chunk asked for); a transient store failure stays a
// TransientError through the reader's context, so the brick loader still retries it. The volumes are made
// byte by byte here, so this suite needs no peer.
#include <gtest/gtest.h>

#include <utility>
#include <vector>

#include <zlib.h>

#include <cstring>
#include <filesystem>
#include <fstream>

#include "cache/formats/precomputed/shard.h"
#include "cache/formats/precomputed/source.h"
#include "core/util/error.h"
#include "tests/test_util.h"

namespace sl {
namespace {

namespace fs = std::filesystem;

void write_file(const fs::path& p, const std::vector<std::byte>& b) {
  fs::create_directories(p.parent_path());
  std::ofstream f(p, std::ios::binary);
  f.write(reinterpret_cast<const char*>(b.data()), std::streamsize(b.size()));
}

void put_u64(std::vector<std::byte>& b, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) b.push_back(std::byte((v >> (8 * i)) & 0xff));
}
void put_u32(std::vector<std::byte>& b, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) b.push_back(std::byte((v >> (8 * i)) & 0xff));
}

std::string info_json(const std::string& data_type, const std::string& scale_extra,
                      const std::string& encoding = "raw", const std::string& root_extra = "") {
  return "{\"@type\":\"neuroglancer_multiscale_volume\",\"type\":\"image\",\"data_type\":\"" + data_type +
         "\",\"num_channels\":1" + root_extra + ",\"scales\":[{\"key\":\"s0\",\"size\":[8,8,8],\"resolution\":[1,1,1],"
         "\"voxel_offset\":[0,0,0],\"chunk_sizes\":[[8,8,8]],\"encoding\":\"" + encoding + "\"" + scale_extra + "}]}";
}

const std::string kShard = ",\"sharding\":{\"@type\":\"neuroglancer_uint64_sharded_v1\",\"preshift_bits\":0,"
                           "\"hash\":\"identity\",\"minishard_bits\":0,\"shard_bits\":0}";

class PrecomputedBadInput : public ::testing::Test {
 protected:
  void SetUp() override { dir = test::scratch_dir() / "vol"; fs::create_directories(dir); }

  // The one error reading the volume's only chunk gives (through the reader, as the loader would).
  std::string chunk_error() {
    try {
      const precomputed::VolumeReader r(std::make_shared<LocalByteStore>(dir.string()), dir.string(),
                                        std::make_shared<zarr::ChunkCache>(0));
      std::vector<std::byte> box(512 * 4);
      r.read_box(0, ivec3(0), ivec3(8), box.data());
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), dir.string());
      return e.what();
    }
    ADD_FAILURE() << "no error";
    return {};
  }
  void expect_chunk_error(const std::string& what) {
    const std::string m = chunk_error();
    EXPECT_NE(m.find("scale 's0' (level 0) chunk 0-8_0-8_0-8"), std::string::npos) << m;
    EXPECT_NE(m.find(what), std::string::npos) << m;
    EXPECT_EQ(m.find('\n'), std::string::npos) << m;
  }
  void expect_info_error(const std::string& info, const std::string& what) {
    test::write_text(dir / "info", info);
    try {
      open_precomputed(dir.string());
      ADD_FAILURE() << "no error for " << info;
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), dir.string());
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
  }
  // A one-shard volume (minishard and shard bits 0) holding `chunk` for chunk id 0, with the shard index
  // entry and the minishard index as given (offsets relative to the end of the 16-byte shard index).
  void write_shard(const std::vector<std::byte>& chunk, std::uint64_t index_start, std::uint64_t index_end,
                   const std::vector<std::byte>& minishard_index) {
    std::vector<std::byte> f;
    put_u64(f, index_start);
    put_u64(f, index_end);
    f.insert(f.end(), chunk.begin(), chunk.end());
    f.insert(f.end(), minishard_index.begin(), minishard_index.end());
    write_file(dir / "s0" / "0.shard", f);
  }
  std::vector<std::byte> minishard(std::uint64_t size, std::uint64_t offset = 0) {
    std::vector<std::byte> m;
    put_u64(m, 0);  // chunk id 0
    put_u64(m, offset);
    put_u64(m, size);
    return m;
  }
  fs::path dir;
};

TEST_F(PrecomputedBadInput, MissingInfo) {
  try {
    open_precomputed(dir.string());
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no 'info' file"), std::string::npos) << e.what();
  }
}

TEST_F(PrecomputedBadInput, MalformedOrUnsupportedInfo) {
  expect_info_error("{\"type\": \"image\", ", "info: malformed JSON");
  expect_info_error("[1, 2]", "must be a JSON object");
  expect_info_error(info_json("int16", ""), "data_type 'int16' is not supported");
  expect_info_error(info_json("uint8", "", "jpeg"), "scale 's0' (level 0): encoding 'jpeg' is not supported");
  expect_info_error(info_json("uint8", "", "compressed_segmentation"), "compressed_segmentation needs data_type uint32 or uint64");
  expect_info_error(info_json("uint8", "").replace(info_json("uint8", "").find("\"num_channels\":1"), 16, "\"num_channels\":3"),
                    "num_channels 3 is not supported");
  std::string bad_hash = kShard;
  bad_hash.replace(bad_hash.find("identity"), 8, "sha1");
  expect_info_error(info_json("uint8", bad_hash), "scale 's0' (level 0): sharding hash 'sha1'");
  std::string bad_bits = kShard;
  bad_bits.replace(bad_bits.find("\"minishard_bits\":0"), 18, "\"minishard_bits\":40");
  expect_info_error(info_json("uint8", bad_bits), "minishard_bits\" 40 exceeds 32");
  expect_info_error(info_json("uint8", ",\"sharding\":{\"@type\":\"other\"}"), "neuroglancer_uint64_sharded_v1");
  std::string bad_size = info_json("uint8", "");
  bad_size.replace(bad_size.find("[8,8,8],\"res"), 7, "[8,0,8]");
  expect_info_error(bad_size, "\"size\" must hold integers in 1..");
  std::string escape = info_json("uint8", "");
  escape.replace(escape.find("\"s0\""), 4, "\"../s0\"");
  expect_info_error(escape, "key '../s0' has a '..' segment");
  // Keys a server would decode into a way out of the volume's URL, sizes that wrap, voxel sizes no
  // camera can frame: each refused naming the scale and the value.
  for (const auto& [key, why] : std::vector<std::pair<std::string, std::string>>{
           {"%2e%2e/s0", "'..' segment"}, {"%2E%2E%2Fs0", "'..' segment"}, {"%252e%252e/s0", "'..' segment"},
           {"/s0", "absolute path"}, {"s0%5c..", "backslash"}, {".", "inside the volume"}}) {
    std::string k = info_json("uint8", "");
    k.replace(k.find("\"s0\""), 4, "\"" + key + "\"");
    expect_info_error(k, why);
  }
  std::string wrap = info_json("uint8", "");
  wrap.replace(wrap.find("[[8,8,8]]"), 9, "[[1073741824,1073741824,16]]");
  expect_info_error(wrap, "chunk voxels (1073741824 x 1073741824 x 16) overflows 64-bit arithmetic");
  for (const char* res : {"[0,1,1]", "[1e30,1,1]", "[1e-320,1,1]", "[-1,1,1]"}) {
    std::string r = info_json("uint8", "");
    r.replace(r.find("[1,1,1]"), 7, res);
    expect_info_error(r, "\"resolution\"");
  }
  std::string ids = info_json("uint8", kShard);
  ids.replace(ids.find("[8,8,8],\"res"), 7, "[1073741824,1073741824,1073741824]");
  ids.replace(ids.find("[[8,8,8]]"), 9, "[[1,1,1]]");
  expect_info_error(ids, "needs 90 bits of sharded chunk id, more than 64");
  const std::string two = "{\"type\":\"image\",\"data_type\":\"uint8\",\"num_channels\":1,\"scales\":["
                          "{\"key\":\"a\",\"size\":[8,8,8],\"resolution\":[1,1,1],\"voxel_offset\":[0,0,0],\"chunk_sizes\":[[8,8,8]],\"encoding\":\"raw\"},"
                          "{\"key\":\"b\",\"size\":[4,4,8],\"resolution\":[2,2,1],\"voxel_offset\":[0,0,0],\"chunk_sizes\":[[8,8,8]],\"encoding\":\"raw\"}]}";
  expect_info_error(two, "scale 'b' (level 1): size 4x4x8 does not halve the previous scale's 8x8x8");
}

TEST_F(PrecomputedBadInput, RawChunkOfTheWrongSize) {
  test::write_text(dir / "info", info_json("uint8", ""));
  write_file(dir / "s0" / "0-8_0-8_0-8", std::vector<std::byte>(100));
  expect_chunk_error("raw chunk holds 100 bytes, expected 512");
}

TEST_F(PrecomputedBadInput, CorruptGzipChunk) {
  test::write_text(dir / "info", info_json("uint8", ""));
  std::vector<std::byte> b{std::byte{0x1f}, std::byte{0x8b}, std::byte{8}, std::byte{0}, std::byte{1}, std::byte{2}};
  write_file(dir / "s0" / "0-8_0-8_0-8", b);
  expect_chunk_error("gzip data");
}

TEST_F(PrecomputedBadInput, CompressedSegmentationBadOffsets) {
  const std::string cseg = ",\"compressed_segmentation_block_size\":[8,8,8]";
  test::write_text(dir / "info", info_json("uint32", cseg, "compressed_segmentation"));
  std::vector<std::byte> b;
  put_u32(b, 1000);  // channel offset past the end
  put_u32(b, 0);
  write_file(dir / "s0" / "0-8_0-8_0-8", b);
  expect_chunk_error("compressed_segmentation channel offset 1000");

  // One block, 1 bit per voxel: packed indices at channel word 2 (16 words, all ones), the table after
  // them at channel word 18 with one entry; index 1 needs a second entry, past the end. (Channel words
  // count from word 1, the channel offset.)
  b.clear();
  put_u32(b, 1);
  put_u32(b, 18u | (1u << 24));
  put_u32(b, 2u);
  for (int i = 0; i < 16; ++i) put_u32(b, 0xffffffffu);
  put_u32(b, 7u);  // table[0]
  write_file(dir / "s0" / "0-8_0-8_0-8", b);
  expect_chunk_error("lookup-table entry 1 at word 20 lies past the end (20 words)");

  b.resize(10 * 4);  // packed indices cut short
  write_file(dir / "s0" / "0-8_0-8_0-8", b);
  expect_chunk_error("packed indices at word 3 run past the end (10 words)");

  b.clear();
  put_u32(b, 1);
  put_u32(b, 2u | (3u << 24));  // 3 bits: not an encoding
  put_u32(b, 3u);
  write_file(dir / "s0" / "0-8_0-8_0-8", b);
  expect_chunk_error("3 encoded bits");
}

TEST_F(PrecomputedBadInput, IdTooLargeForU32) {
  test::write_text(dir / "info", info_json("uint64", ""));
  std::vector<std::byte> b;
  for (int i = 0; i < 512; ++i) put_u64(b, i == 77 ? (std::uint64_t(1) << 40) : 5);
  write_file(dir / "s0" / "0-8_0-8_0-8", b);
  expect_chunk_error("label id 1099511627776 does not fit in 32 bits");
}

TEST_F(PrecomputedBadInput, ShardIndexPastTheEnd) {
  test::write_text(dir / "info", info_json("uint8", kShard));
  write_shard(std::vector<std::byte>(512), 512, 5000, minishard(512));
  expect_chunk_error("lies past the end of the");
}

TEST_F(PrecomputedBadInput, ShardIndexEndsBeforeItStarts) {
  test::write_text(dir / "info", info_json("uint8", kShard));
  write_shard(std::vector<std::byte>(512), 536, 512, minishard(512));
  expect_chunk_error("shard index entry ends (512) before it starts (536)");
}

TEST_F(PrecomputedBadInput, MinishardIndexOfTheWrongLength) {
  test::write_text(dir / "info", info_json("uint8", kShard));
  std::vector<std::byte> m = minishard(512);
  m.push_back(std::byte{0});
  write_shard(std::vector<std::byte>(512), 512, 512 + 25, m);
  expect_chunk_error("minishard index of 25 bytes is not 24 bytes per chunk");
}

TEST_F(PrecomputedBadInput, ChunkInShardPastTheEnd) {
  test::write_text(dir / "info", info_json("uint8", kShard));
  write_shard(std::vector<std::byte>(512), 512, 536, minishard(4096, 536));  // starts where the file ends
  expect_chunk_error("lies past the end of the");
}

TEST_F(PrecomputedBadInput, ChunkInShardOverflowing) {
  test::write_text(dir / "info", info_json("uint8", kShard));
  write_shard(std::vector<std::byte>(512), 512, 536, minishard(16, ~std::uint64_t(0) - 8));
  expect_chunk_error("minishard index entry 0 overflows 64 bits");
}

TEST_F(PrecomputedBadInput, ChunkOverlapsItsMinishardIndex) {
  test::write_text(dir / "info", info_json("uint8", kShard));
  write_shard(std::vector<std::byte>(512), 512, 536, minishard(512, 24));
  expect_chunk_error("minishard index entry 0 (bytes 40+512) overlaps the minishard index itself (bytes 528-552)");
}

TEST_F(PrecomputedBadInput, ChunkInShardOfTheWrongSize) {
  test::write_text(dir / "info", info_json("uint8", kShard));
  write_shard(std::vector<std::byte>(512), 512, 536, minishard(300));
  expect_chunk_error("raw chunk holds 300 bytes, expected 512");
}

TEST_F(PrecomputedBadInput, GoodShardReads) {
  // The hand-made shard the cases above corrupt, intact: it reads (so they fail for their reason).
  test::write_text(dir / "info", info_json("uint8", kShard));
  std::vector<std::byte> chunk(512);
  for (std::size_t i = 0; i < chunk.size(); ++i) chunk[i] = std::byte(i % 251);
  write_shard(chunk, 512, 536, minishard(512));
  const precomputed::VolumeReader r(std::make_shared<LocalByteStore>(dir.string()), dir.string(),
                                    std::make_shared<zarr::ChunkCache>(0));
  std::vector<std::byte> box(512);
  r.read_box(0, ivec3(0), ivec3(8), box.data());
  EXPECT_EQ(box, chunk);
}

// The intact volume through the program: `info` (bare and with the precomputed:// prefix) prints the
// scale and its sharding; bench streams it and says what it read; a labelled render takes it as its own
// segmentation.
TEST_F(PrecomputedBadInput, GoodShardThroughTheProgram) {
  test::write_text(dir / "info", info_json("uint8", kShard));
  std::vector<std::byte> chunk(512, std::byte{200});
  write_shard(chunk, 512, 536, minishard(512));
  for (const std::string& prefix : {std::string(), std::string("precomputed://")}) {
    const test::RunResult r = test::run_sparseleap("info " + prefix + dir.string());
    ASSERT_EQ(r.exit_code, 0) << r.output;
    for (const char* s : {"Neuroglancer precomputed, image", "8 x 8 x 8", "'s0'", "chunks 8x8x8  raw",
                          "sharded: neuroglancer_uint64_sharded_v1 (preshift 0, minishard 0, shard 0 bits; identity hash"}) {
      EXPECT_NE(r.output.find(s), std::string::npos) << s << " in " << r.output;
    }
  }
  const test::RunResult r = test::run_sparseleap("bench --volume " + dir.string() +
                                                 " --cache-mb 8 --brick 8 --block 8 --orbit 1 --size 16x16 --max-frames-per-view 4");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("store: "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(" requests, "), std::string::npos) << r.output;
}

// A store whose every chunk read fails transiently (as a timeout would): the reader adds the scale and
// chunk and keeps the error a TransientError.
class FlakyStore final : public ByteStore {
 public:
  explicit FlakyStore(std::string root) : local_(std::move(root)) {}
  std::optional<std::vector<std::byte>> read(const std::string& key, std::uint64_t max_bytes) const override {
    if (key == "info") return local_.read(key, max_bytes);
    throw TransientError("", "timed out");
  }
  std::optional<std::vector<std::byte>> read_range(const std::string&, std::uint64_t, std::uint64_t) const override {
    throw TransientError("", "timed out");
  }
  std::optional<std::vector<std::byte>> read_suffix(const std::string&, std::uint64_t) const override {
    throw TransientError("", "timed out");
  }

 private:
  LocalByteStore local_;
};

TEST_F(PrecomputedBadInput, TransientFailuresStayTransient) {
  for (const std::string& extra : {std::string(), kShard}) {
    test::write_text(dir / "info", info_json("uint8", extra));
    const precomputed::VolumeReader r(std::make_shared<FlakyStore>(dir.string()), "flaky", std::make_shared<zarr::ChunkCache>(0));
    std::vector<std::byte> box(512);
    try {
      r.read_box(0, ivec3(0), ivec3(8), box.data());
      FAIL();
    } catch (const TransientError& e) {
      EXPECT_EQ(e.file(), "flaky");
      EXPECT_NE(std::string(e.what()).find("scale 's0' (level 0) chunk 0-8_0-8_0-8"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("timed out"), std::string::npos) << e.what();
    }
  }
}

TEST_F(PrecomputedBadInput, LabelVolumeMustMatch) {
  test::write_text(dir / "info", info_json("uint8", ""));
  const fs::path lab = dir.parent_path() / "lab";
  fs::create_directories(lab);
  std::string other = info_json("uint32", "");
  other.replace(other.find("[8,8,8],\"res"), 7, "[8,8,4]");
  test::write_text(lab / "info", other);
  try {
    open_precomputed(dir.string(), lab.string());
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), lab.string());
    EXPECT_NE(std::string(e.what()).find("label volume size differs"), std::string::npos) << e.what();
  }
  test::write_text(lab / "info", info_json("float32", ""));
  try {
    open_precomputed(dir.string(), lab.string());
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("labels must be of an integer type"), std::string::npos) << e.what();
  }
}

// Through the program: one error line naming the volume, the scale and the chunk, and a non-zero exit,
// in core and out of core (where the coarsest scale is read at start); `info --stats` has printed the
// info before it reads the data.
TEST_F(PrecomputedBadInput, CommandLineSaysOneLine) {
  test::write_text(dir / "info", info_json("uint8", ""));
  write_file(dir / "s0" / "0-8_0-8_0-8", std::vector<std::byte>(100));
  const std::string out = (dir.parent_path() / "o").string();
  for (const std::string& cmd : {"render --size 8x8 --out " + out + " --volume ",
                                 "render --size 8x8 --cache-mb 8 --out " + out + " --volume precomputed://",
                                 std::string("info --stats ")}) {
    const test::RunResult r = test::run_sparseleap(cmd + dir.string());
    EXPECT_NE(r.exit_code, 0) << cmd;
    EXPECT_NE(r.output.find(dir.string() + ": scale 's0' (level 0) chunk 0-8_0-8_0-8: raw chunk holds 100 bytes"),
              std::string::npos)
        << cmd << ": " << r.output;
    int errors = 0;
    for (std::size_t i = 0; (i = r.output.find("error", i)) != std::string::npos; ++i) ++errors;
    EXPECT_EQ(errors, 1) << cmd << ": " << r.output;
    EXPECT_EQ(r.output.back(), '\n');
    EXPECT_EQ(r.output.find('\n'), cmd.starts_with("info") ? r.output.find('\n') : r.output.size() - 1) << r.output;
  }
}

}  // namespace
}  // namespace sl
