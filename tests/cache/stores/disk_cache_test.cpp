// DiskCache and CachedByteStore: entries survive a restart (the index is rebuilt from the
// directory, LRU order from the files' times); the byte bound evicts the least recently used; short,
// corrupt and foreign files are detected and refetched; a temporary file a crash left behind is
// removed and never read; files not the cache's own are never touched; over HTTP a second read of an
// object makes no request.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>

#include "cache/stores/disk_cache.h"
#include "cache/stores/http_store.h"
#include "core/util/error.h"
#include "tests/http_test_server.h"
#include "tests/test_util.h"

namespace sl {
namespace {

namespace fs = std::filesystem;

std::vector<std::byte> payload(std::size_t n, int seed) {
  std::vector<std::byte> b(n);
  for (std::size_t i = 0; i < n; ++i) b[i] = std::byte((i * 7 + std::size_t(seed)) & 0xff);
  return b;
}

std::vector<fs::path> entry_files(const fs::path& dir) {
  std::vector<fs::path> v;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (e.path().filename().string().size() == 16) v.push_back(e.path());
  }
  return v;
}

TEST(DiskCache, EntriesSurviveARestart) {
  const fs::path dir = test::scratch_dir() / "dc";
  {
    DiskCache c(dir.string(), 1 << 20);
    EXPECT_FALSE(c.get("http://h/a").has_value());
    c.put("http://h/a", payload(1000, 1));
    c.put("http://h/b#0+10", payload(10, 2));
    EXPECT_EQ(c.get("http://h/a"), payload(1000, 1));
    EXPECT_EQ(c.files(), 2u);
  }
  DiskCache c(dir.string(), 1 << 20);
  EXPECT_EQ(c.files(), 2u);
  EXPECT_EQ(c.get("http://h/a"), payload(1000, 1));
  EXPECT_EQ(c.get("http://h/b#0+10"), payload(10, 2));
  EXPECT_FALSE(c.get("http://h/b").has_value());
  EXPECT_EQ(c.counters().hits, 2u);
}

TEST(DiskCache, EvictsLeastRecentlyUsedToTheBound) {
  const fs::path dir = test::scratch_dir() / "dc";
  const std::size_t entry = 1000 + 28 + 3;  // payload + header + key
  DiskCache c(dir.string(), 3 * entry);
  c.put("k/1", payload(1000, 1));
  c.put("k/2", payload(1000, 2));
  c.put("k/3", payload(1000, 3));
  EXPECT_TRUE(c.get("k/1").has_value());  // now k/2 is the least recently used
  c.put("k/4", payload(1000, 4));
  EXPECT_EQ(c.files(), 3u);
  EXPECT_LE(c.bytes(), 3 * entry);
  EXPECT_FALSE(c.get("k/2").has_value());
  EXPECT_TRUE(c.get("k/1").has_value());
  EXPECT_TRUE(c.get("k/4").has_value());
  EXPECT_EQ(c.counters().evicted, 1u);
  EXPECT_EQ(entry_files(dir).size(), 3u);
  // A restart with a smaller bound evicts down to it, oldest first.
  DiskCache smaller(dir.string(), entry);
  EXPECT_EQ(smaller.files(), 1u);
  EXPECT_EQ(entry_files(dir).size(), 1u);
}

TEST(DiskCache, CorruptShortAndLeftoverFilesAreDetected) {
  const fs::path dir = test::scratch_dir() / "dc";
  {
    DiskCache c(dir.string(), 1 << 20);
    c.put("a", payload(500, 1));
    c.put("b", payload(500, 2));
  }
  std::vector<fs::path> files = entry_files(dir);
  ASSERT_EQ(files.size(), 2u);
  {
    // One flipped payload byte in the first file, the second cut short (a torn write).
    std::fstream f(files[0], std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(200);
    f.put('\x55');
  }
  fs::resize_file(files[1], 100);
  // A temporary file a crash left, and a file that is not the cache's.
  test::write_text(files[0].string() + ".tmp.1234.0", "half");
  test::write_text(dir / "notes.txt", "mine");
  DiskCache c(dir.string(), 1 << 20);
  EXPECT_FALSE(fs::exists(files[0].string() + ".tmp.1234.0"));
  EXPECT_TRUE(fs::exists(dir / "notes.txt"));
  EXPECT_FALSE(c.get("a").has_value());
  EXPECT_FALSE(c.get("b").has_value());
  EXPECT_EQ(c.counters().corrupt, 2u);
  EXPECT_EQ(c.files(), 0u);
  EXPECT_TRUE(entry_files(dir).empty());  // deleted: the next read refetches and rewrites
  c.put("a", payload(500, 1));
  EXPECT_EQ(c.get("a"), payload(500, 1));
}

TEST(DiskCache, UnusableDirectoryIsOneClearError) {
  const fs::path file = test::scratch_dir() / "plain";
  test::write_text(file, "x");
  try {
    DiskCache c(file.string(), 1 << 20);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "--disk-cache");
    EXPECT_EQ(e.reason().rfind(file.string() + ": cannot create the directory", 0), 0u) << e.what();
  }
}

TEST(CachedByteStore, SecondReadsComeFromDisk) {
  const fs::path dir = test::scratch_dir();
  fs::create_directories(dir / "root");
  std::string content(5000, 'x');
  for (std::size_t i = 0; i < content.size(); ++i) content[i] = char(i % 13);
  test::write_text(dir / "root" / "obj", content);
  test::HttpTestServer server(dir / "root");
  const auto http = std::make_shared<HttpByteStore>(server.url());
  for (int run = 0; run < 2; ++run) {
    SCOPED_TRACE(run);
    auto cache = std::make_shared<DiskCache>((dir / "dc").string(), 1 << 20);  // a new process, same DIR
    const CachedByteStore s(http, server.url(), cache);
    const std::uint64_t before = http_counters().requests;
    const auto whole = s.read("obj", kMaxChunkObjectBytes);
    const auto range = s.read_range("obj", 100, 200);
    const auto suffix = s.read_suffix("obj", 64);
    ASSERT_TRUE(whole && range && suffix);
    EXPECT_EQ(std::string(reinterpret_cast<const char*>(whole->data()), whole->size()), content);
    EXPECT_EQ(std::memcmp(range->data(), content.data() + 100, 200), 0);
    EXPECT_EQ(std::memcmp(suffix->data(), content.data() + content.size() - 64, 64), 0);
    EXPECT_EQ(http_counters().requests - before, run == 0 ? 3u : 0u);
    EXPECT_EQ(cache->counters().hits, run == 0 ? 0u : 3u);
    EXPECT_FALSE(s.read("missing", kMaxChunkObjectBytes).has_value());  // not cached: asked each time
  }
}

}  // namespace
}  // namespace sl
