// DiskCache and CachedByteStore: entries survive a restart (the index is rebuilt from the
// directory, LRU order from the files' times); the byte bound evicts the least recently used; short,
// corrupt and foreign files are detected and refetched; a temporary file a crash left behind is
// removed and never read; files not the cache's own are never touched (a folder of other files is
// refused, foreign files and symlinks put into a cache survive eviction byte-identical); over HTTP a
// second read of an object makes no request.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>
#include <functional>
#include <map>

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
  for (const auto& e : fs::directory_iterator(dir / DiskCache::kEntriesName)) {
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
  test::write_text(dir / DiskCache::kEntriesName / "notes.txt", "mine");
  DiskCache c(dir.string(), 1 << 20);
  EXPECT_FALSE(fs::exists(files[0].string() + ".tmp.1234.0"));
  EXPECT_EQ(test::read_text(dir / DiskCache::kEntriesName / "notes.txt"), "mine");
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
    EXPECT_EQ(e.reason(), file.string() + ": not a directory") << e.what();
  }
}

// ---- Ownership: the cache deletes only what it wrote -------------------------------------------

// Every file below `dir` with its bytes (symlinks as their target), to prove foreign files survive
// byte-identical.
std::map<std::string, std::string> contents(const fs::path& dir) {
  std::map<std::string, std::string> m;
  for (auto it = fs::recursive_directory_iterator(dir); it != fs::recursive_directory_iterator(); ++it) {
    const std::string rel = fs::relative(it->path(), dir).string();
    if (it->is_symlink()) m[rel] = "-> " + fs::read_symlink(it->path()).string();
    else if (it->is_regular_file()) m[rel] = test::read_text(it->path());
    else m[rel] = "dir";
  }
  return m;
}

std::string error_of(const fs::path& dir) {
  try {
    DiskCache c(dir.string(), 1 << 20);
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "--disk-cache");
    return e.reason();
  }
  return "no error";
}

TEST(DiskCacheOwnership, NewAndEmptyFoldersBecomeCachesAndAreReAdopted) {
  const fs::path dir = test::scratch_dir();
  fs::create_directories(dir / "empty");
  for (const fs::path d : {dir / "new" / "deeper", dir / "empty"}) {
    SCOPED_TRACE(d);
    {
      DiskCache c(d.string(), 1 << 20);
      c.put("k", payload(100, 1));
    }
    EXPECT_EQ(test::read_text(d / DiskCache::kMarkerName), "sparseleap disk cache 1\n");
    EXPECT_TRUE(fs::is_directory(d / DiskCache::kEntriesName));
    DiskCache again(d.string(), 1 << 20);  // ours: adopted with its entry
    EXPECT_EQ(again.get("k"), payload(100, 1));
  }
}

TEST(DiskCacheOwnership, AFolderOfOtherFilesIsRefusedAndUntouched) {
  const fs::path dir = test::scratch_dir();
  const fs::path outside = dir / "outside";
  fs::create_directories(outside);
  test::write_text(outside / "precious", "outside the cache");
  const std::vector<std::pair<std::string, std::function<void(const fs::path&)>>> variants = {
      {"a file at the top", [](const fs::path& d) { test::write_text(d / "notes.txt", "mine"); }},
      {"a hidden file", [](const fs::path& d) { test::write_text(d / ".profile", "mine"); }},
      {"a file named like an entry", [](const fs::path& d) { test::write_text(d / "0123456789abcdef", "mine"); }},
      {"a subfolder of files", [](const fs::path& d) {
         fs::create_directories(d / "sub");
         test::write_text(d / "sub" / "0123456789abcdef", "mine");
       }},
      {"a folder named entries", [](const fs::path& d) {
         fs::create_directories(d / "entries");
         test::write_text(d / "entries" / "0123456789abcdef", "SLDCACH1 but not ours");
       }},
      {"a symlink out", [&](const fs::path& d) { fs::create_directory_symlink(outside, d / "link"); }},
      {"a marker of other content", [](const fs::path& d) { test::write_text(d / ".sparseleap-disk-cache", "mine\n"); }},
      {"a marker that is a symlink", [&](const fs::path& d) {
         fs::create_symlink(outside / "precious", d / ".sparseleap-disk-cache");
       }},
      {"a marker that is a directory", [](const fs::path& d) { fs::create_directories(d / ".sparseleap-disk-cache"); }},
  };
  for (std::size_t i = 0; i < variants.size(); ++i) {
    SCOPED_TRACE(variants[i].first);
    const fs::path d = dir / ("v" + std::to_string(i));
    fs::create_directories(d);
    variants[i].second(d);
    const auto before = contents(d);
    const std::string why = error_of(d);
    EXPECT_EQ(why.rfind(d.string() + ": ", 0), 0u) << why;
    EXPECT_NE(why.find("new or empty folder"), std::string::npos) << why;
    EXPECT_EQ(contents(d), before);
  }
  EXPECT_EQ(test::read_text(outside / "precious"), "outside the cache");
}

TEST(DiskCacheOwnership, EvictionDeletesOnlyTheCachesOwnFiles) {
  const fs::path dir = test::scratch_dir();
  const fs::path d = dir / "dc", outside = dir / "outside";
  fs::create_directories(outside);
  test::write_text(outside / "precious", "outside the cache");
  test::write_text(outside / "0123456789abcdef", "named like an entry, outside");
  { DiskCache c(d.string(), 1 << 20); }
  // Foreign things put into the cache's own folder and subfolder after it was made.
  const fs::path e = d / DiskCache::kEntriesName;
  test::write_text(d / "notes.txt", "mine");
  test::write_text(d / "fedcba9876543210", "named like an entry, at the top");
  test::write_text(e / "00000000000000aa", "named like an entry, no magic");
  fs::create_symlink(outside / "0123456789abcdef", e / "00000000000000bb");
  fs::create_directory_symlink(outside, e / "00000000000000cc");
  test::write_text(e / "readme", "mine too");
  const auto foreign = contents(d);
  const auto outside_before = contents(outside);
  {
    // A bound of one entry (header, key of 3 or 4 bytes, payload): every put evicts the one before.
    DiskCache c(d.string(), 28 + 4 + 1000);
    EXPECT_EQ(c.files(), 0u);
    for (int i = 0; i < 20; ++i) c.put("k/" + std::to_string(i), payload(1000, i));
    EXPECT_EQ(c.files(), 1u);
    EXPECT_GE(c.counters().evicted, 19u);
  }
  DiskCache c(d.string(), 1);  // a restart with a bound below every entry
  auto after = contents(d);
  for (const auto& [name, bytes] : foreign) {
    EXPECT_EQ(after.count(name), 1u) << name;
    if (after.count(name)) EXPECT_EQ(after.at(name), bytes) << name;
  }
  EXPECT_EQ(contents(outside), outside_before);
}

TEST(DiskCacheOwnership, ASymlinkOrFileInPlaceOfAnEntryIsNeverFollowedOrDeleted) {
  const fs::path dir = test::scratch_dir();
  const fs::path d = dir / "dc", outside = dir / "outside";
  fs::create_directories(outside);
  {
    DiskCache c(d.string(), 1 << 20);
    c.put("a", payload(300, 1));
    c.put("b", payload(300, 2));
  }
  const std::vector<fs::path> files = entry_files(d);
  ASSERT_EQ(files.size(), 2u);
  // A cache entry copied outside, and a symlink to it where the entry was: never read or deleted.
  fs::copy_file(files[0], outside / "copy");
  DiskCache c(d.string(), 1 << 20);
  fs::remove(files[0]);
  fs::create_symlink(outside / "copy", files[0]);
  fs::remove(files[1]);
  test::write_text(files[1], "not an entry any more");
  EXPECT_FALSE(c.get("a").has_value());
  EXPECT_FALSE(c.get("b").has_value());
  EXPECT_TRUE(fs::is_symlink(files[0]));
  EXPECT_EQ(test::read_text(files[1]), "not an entry any more");
  EXPECT_TRUE(fs::exists(outside / "copy"));
}

TEST(DiskCacheOwnership, EntriesThatIsNotADirectoryIsRefused) {
  const fs::path dir = test::scratch_dir();
  fs::create_directories(dir / "outside");
  const fs::path a = dir / "a", b = dir / "b";
  { DiskCache c(a.string(), 1 << 20); }
  { DiskCache c(b.string(), 1 << 20); }
  fs::remove_all(a / DiskCache::kEntriesName);
  test::write_text(a / DiskCache::kEntriesName, "mine");
  fs::remove_all(b / DiskCache::kEntriesName);
  fs::create_directory_symlink(dir / "outside", b / DiskCache::kEntriesName);
  for (const fs::path& d : {a, b}) {
    EXPECT_EQ(error_of(d), d.string() + ": entries is not a directory of the cache's own (a file or a symlink)");
  }
  EXPECT_EQ(test::read_text(a / DiskCache::kEntriesName), "mine");
}

// Root writes into any folder: the check runs as an unprivileged user in a child process.
TEST(DiskCacheOwnership, AnUnwritableFolderIsOneClearError) {
  const fs::path scratch = test::scratch_dir(), d = scratch / "ro";
  fs::create_directories(d);
  fs::permissions(d, fs::perms::owner_read | fs::perms::owner_exec | fs::perms::group_read |
                         fs::perms::group_exec | fs::perms::others_read | fs::perms::others_exec);
  fs::permissions(scratch, fs::perms::others_exec | fs::perms::others_read, fs::perm_options::add);
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    if (::geteuid() == 0 && (::setgid(65534) != 0 || ::setuid(65534) != 0)) ::_exit(10);
    try {
      DiskCache c(d.string(), 1 << 20);
    } catch (const InputError& e) {
      ::_exit(e.reason().rfind(d.string() + ": the directory is not writable", 0) == 0 ? 0 : 11);
    } catch (...) {
      ::_exit(12);
    }
    ::_exit(13);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0);
  EXPECT_TRUE(fs::is_empty(d));
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
