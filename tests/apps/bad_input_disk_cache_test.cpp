// The bad-input corpus (bad_input_harness.h): `--disk-cache DIR` given a folder it must not adopt.
// The cache deletes only what it wrote, so a folder of other files, a marker or `entries` that is not
// its own, or a DIR that is no folder is one line naming DIR, exit 1; the harness's snapshot of the
// case folder (every entry's type, size, mtime and content hash) proves the foreign files survive
// byte-identical, symlinks and what they point to included. A cache that is its own but sits beside a
// bad volume is adopted without a change to anything in it.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include "cache/stores/disk_cache.h"
#include "tests/apps/bad_input_harness.h"

namespace sl::bad_input {
namespace {

const std::string kMarkerText = "sparseleap disk cache 1\n";
// An entry as the cache writes it begins with this magic; a file that has it but lies outside
// `entries/` is still not the cache's.
const std::string kEntryMagic = "SLDCACH1";

// dc/ holding a foreign layout made by `fn`, plus a precious file outside dc/ that a symlink may point to.
Make folder(std::function<void(const fs::path&)> fn) {
  return [=](const fs::path& d) {
    fs::create_directories(d / "dc");
    fs::create_directories(d / "outside");
    write_bytes(d / "outside" / "precious", "outside the cache");
    write_bytes(d / "outside" / "0123456789abcdef", kEntryMagic + "named like an entry, outside");
    fn(d / "dc");
  };
}
// A cache of our own (marker and entries/), then `fn`.
Make own_cache(std::function<void(const fs::path&)> fn) {
  return folder([=](const fs::path& dc) {
    write_bytes(dc / DiskCache::kMarkerName, kMarkerText);
    fs::create_directories(dc / DiskCache::kEntriesName);
    fn(dc);
  });
}
Make fifo(const std::string& name) {
  return [=](const fs::path& d) { ASSERT_EQ(::mkfifo((d / name).c_str(), 0644), 0); };
}

std::vector<Case> disk_cache_cases() {
  const std::string r = kRenderSmall + "--disk-cache dc";
  const std::string refused = "--disk-cache: dc: holds files and is not a sparseleap disk cache";
  const std::string not_ours = "is not a sparseleap disk cache's marker";
  return {
      {"disk-cache", "a file at the top", folder([](const fs::path& dc) { write_bytes(dc / "notes.txt", "mine"); }), r,
       1, refused},
      {"disk-cache", "a hidden file", folder([](const fs::path& dc) { write_bytes(dc / ".profile", "mine"); }), r, 1,
       refused},
      {"disk-cache", "a file named like an entry",
       folder([](const fs::path& dc) { write_bytes(dc / "0123456789abcdef", "mine"); }), r, 1, refused},
      {"disk-cache", "an old cache's entry at the top",
       folder([](const fs::path& dc) { write_bytes(dc / "0123456789abcdef", kEntryMagic + std::string(40, '\0')); }), r,
       1, refused},
      {"disk-cache", "a temporary's name at the top",
       folder([](const fs::path& dc) { write_bytes(dc / "0123456789abcdef.tmp.12.0", "mine"); }), r, 1, refused},
      {"disk-cache", "files in a subfolder", folder([](const fs::path& dc) {
         fs::create_directories(dc / "photos" / "2026");
         write_bytes(dc / "photos" / "2026" / "a.jpg", Bytes(3000, '\x7f'));
         write_bytes(dc / "photos" / "0123456789abcdef", "mine");
       }), r, 1, refused},
      {"disk-cache", "an empty subfolder", folder([](const fs::path& dc) { fs::create_directories(dc / "keep"); }), r,
       1, refused},
      {"disk-cache", "a folder named entries without the marker", folder([](const fs::path& dc) {
         fs::create_directories(dc / "entries");
         write_bytes(dc / "entries" / "0123456789abcdef", kEntryMagic + "mine");
       }), r, 1, refused},
      {"disk-cache", "a symlink to a folder outside",
       folder([](const fs::path& dc) { fs::create_directory_symlink("../outside", dc / "link"); }), r, 1, refused},
      {"disk-cache", "a symlink named like an entry to a file outside",
       folder([](const fs::path& dc) { fs::create_symlink("../outside/precious", dc / "fedcba9876543210"); }), r, 1,
       refused},
      {"disk-cache", "a dangling symlink", folder([](const fs::path& dc) { fs::create_symlink("nowhere", dc / "gone"); }),
       r, 1, refused},
      {"disk-cache", "a FIFO in the folder", folder([](const fs::path& dc) { ASSERT_EQ(::mkfifo((dc / "pipe").c_str(), 0644), 0); }),
       r, 1, refused},
      {"disk-cache", "a marker of other content", folder([](const fs::path& dc) {
         write_bytes(dc / DiskCache::kMarkerName, "mine\n");
         write_bytes(dc / "notes.txt", "mine");
       }), r, 1, not_ours},
      {"disk-cache", "a marker with more after its line",
       folder([](const fs::path& dc) { write_bytes(dc / DiskCache::kMarkerName, kMarkerText + "and more\n"); }), r, 1,
       not_ours},
      {"disk-cache", "an empty marker", folder([](const fs::path& dc) { write_bytes(dc / DiskCache::kMarkerName, ""); }),
       r, 1, not_ours},
      {"disk-cache", "a marker that is a symlink to a file of the right text", folder([](const fs::path& dc) {
         write_bytes(dc.parent_path() / "outside" / "fake-marker", kMarkerText);
         fs::create_symlink("../outside/fake-marker", dc / DiskCache::kMarkerName);
       }), r, 1, not_ours},
      {"disk-cache", "a marker that is a directory",
       folder([](const fs::path& dc) { fs::create_directories(dc / DiskCache::kMarkerName); }), r, 1, not_ours},
      {"disk-cache", "a marker that is a FIFO", folder([](const fs::path& dc) {
         ASSERT_EQ(::mkfifo((dc / DiskCache::kMarkerName).c_str(), 0644), 0);
       }), r, 1, not_ours},
      {"disk-cache", "entries is a file", own_cache([](const fs::path& dc) {
         fs::remove(dc / DiskCache::kEntriesName);
         write_bytes(dc / DiskCache::kEntriesName, "mine");
       }), r, 1, "dc: entries is not a directory of the cache's own"},
      {"disk-cache", "entries is a symlink to a folder outside", own_cache([](const fs::path& dc) {
         fs::remove(dc / DiskCache::kEntriesName);
         fs::create_directory_symlink("../outside", dc / DiskCache::kEntriesName);
       }), r, 1, "dc: entries is not a directory of the cache's own"},
      {"disk-cache", "the folder is a file", file("dc", "mine"), r, 1, "--disk-cache: dc: not a directory"},
      {"disk-cache", "the folder is a FIFO", fifo("dc"), r, 1, "--disk-cache: dc: not a directory"},
      {"disk-cache", "the folder is a symlink to a folder of other files", [](const fs::path& d) {
         fs::create_directories(d / "mine");
         write_bytes(d / "mine" / "notes.txt", "mine");
         fs::create_directory_symlink("mine", d / "dc");
       }, r, 1, refused},
      {"disk-cache", "the folder lies below a file", file("plain", "mine"), kRenderSmall + "--disk-cache plain/dc", 1,
       "--disk-cache: plain/dc: cannot create the directory"},
      {"disk-cache", "the folder with a trailing slash",
       folder([](const fs::path& dc) { write_bytes(dc / "notes.txt", "mine"); }), kRenderSmall + "--disk-cache dc/", 1,
       "--disk-cache: dc/: holds files"},
      {"disk-cache", "bench, a folder of other files",
       folder([](const fs::path& dc) { write_bytes(dc / "notes.txt", "mine"); }),
       "bench --volume builtin:neurites:16x16x16 --size 8x8 --orbit 1 --disk-cache dc", 1, refused},
      {"disk-cache", "our cache with foreign files beside a missing volume", own_cache([](const fs::path& dc) {
         write_bytes(dc / "notes.txt", "mine");
         write_bytes(dc / "0123456789abcdef", kEntryMagic + "at the top");
         write_bytes(dc / DiskCache::kEntriesName / "readme", "mine too");
         write_bytes(dc / DiskCache::kEntriesName / "00000000000000aa", "named like an entry, no magic");
         fs::create_symlink("../../outside/0123456789abcdef", dc / DiskCache::kEntriesName / "00000000000000bb");
         fs::create_directory_symlink("../../outside", dc / DiskCache::kEntriesName / "00000000000000cc");
       }), kRender + "--volume missing.nrrd --disk-cache dc", 1, "missing.nrrd"},
      {"disk-cache", "--disk-cache-mb 0", kNothing, kRenderSmall + "--disk-cache dc --disk-cache-mb 0", 1,
       "--disk-cache-mb: must be positive, got 0"},
  };
}

TEST(BadInputCorpus, DiskCache) { run_corpus(disk_cache_cases()); }

}  // namespace
}  // namespace sl::bad_input
