// HttpByteStore against the tests' own server on 127.0.0.1 (tests/data_tools/http_server.py):
// whole objects, ranges and suffix ranges equal to the local file; 404 = nullopt; 403 and ranges past
// the end = errors naming the URL; a server ignoring Range is sliced and counted; 500s, dropped
// connections, truncated range bodies and stalls retried, then TransientError; a stall never hangs past
// the timeout. Zarr v2 and v3 (sharded, index at start and end; ours and zarr-python 3's) read through
// HTTP voxel for voxel as local; metadata 404/403 one clear error naming the URL.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <thread>

#include "cache/formats/zarr/meta.h"
#include "cache/formats/zarr/source.h"
#include "cache/stores/http_store.h"
#include "cache/stores/store_url.h"
#include "core/util/error.h"
#include "tests/cache/formats/zarr_bricks_match.h"
#include "tests/cache/formats/zarr_test_util.h"
#include "tests/http_test_server.h"
#include "tests/test_util.h"

namespace sl {
namespace {

namespace fs = std::filesystem;

std::vector<std::byte> bytes_of(const std::string& s) {
  std::vector<std::byte> b(s.size());
  std::memcpy(b.data(), s.data(), s.size());
  return b;
}

// A directory `root` with one 1000-byte object "a/obj" (bytes i % 251).
fs::path object_root(std::string& content) {
  const fs::path root = test::scratch_dir() / "root";
  fs::create_directories(root / "a");
  content.clear();
  for (int i = 0; i < 1000; ++i) content.push_back(char(i % 251));
  test::write_text(root / "a" / "obj", content);
  return root;
}

HttpOptions quick(int tries = 3, long timeout_ms = 2000) {
  HttpOptions o;
  o.tries = tries;
  o.timeout_ms = timeout_ms;
  o.connect_timeout_ms = timeout_ms;
  o.low_speed_time_s = 1;
  o.backoff_ms = 10;
  return o;
}

TEST(HttpByteStore, ObjectsRangesSuffixesAndMissing) {
  std::string content;
  const fs::path root = object_root(content);
  test::HttpTestServer server(root);
  const HttpByteStore s(server.url(), quick());
  const std::uint64_t before = http_counters().requests, connections = http_counters().connections;
  EXPECT_EQ(s.read("a/obj", kMaxChunkObjectBytes), bytes_of(content));
  EXPECT_EQ(s.read_range("a/obj", 100, 50), bytes_of(content.substr(100, 50)));
  EXPECT_EQ(s.read_range("a/obj", 0, 1000), bytes_of(content));
  EXPECT_EQ(s.read_suffix("a/obj", 16), bytes_of(content.substr(984)));
  EXPECT_FALSE(s.read("a/none", kMaxChunkObjectBytes).has_value());
  EXPECT_FALSE(s.read_range("none", 0, 4).has_value());
  EXPECT_FALSE(s.read_suffix("none", 4).has_value());
  EXPECT_EQ(http_counters().requests - before, 7u);
  EXPECT_EQ(http_counters().connections - connections, 1u);  // one kept-alive connection for all seven
  // Past the end: a permanent error naming the URL and the size.
  try {
    s.read_range("a/obj", 990, 20);
    FAIL() << "no error";
  } catch (const TransientError& e) {
    FAIL() << "transient: " << e.what();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(server.url("a/obj")), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("1000-byte object"), std::string::npos) << e.what();
  }
  EXPECT_THROW(s.read_range("a/obj", 2000, 5), InputError);
  EXPECT_THROW(s.read_suffix("a/obj", 2000), InputError);
  EXPECT_GE(server.log().size(), 7u);
}

TEST(HttpByteStore, ParallelRequestsFromManyThreads) {
  std::string content;
  const fs::path root = object_root(content);
  test::HttpTestServer server(root);
  const HttpByteStore s(server.url(), quick());
  std::vector<std::thread> threads;
  std::atomic<int> bad{0};
  for (int t = 0; t < 8; ++t) {
    threads.emplace_back([&, t] {
      for (int i = 0; i < 20; ++i) {
        const std::uint64_t off = std::uint64_t((t * 37 + i * 11) % 900);
        if (s.read_range("a/obj", off, 64) != bytes_of(content.substr(off, 64))) ++bad;
      }
    });
  }
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(bad, 0);
}

TEST(HttpByteStore, ServerIgnoringRangeIsSlicedAndCounted) {
  std::string content;
  const fs::path root = object_root(content);
  test::HttpTestServer server(root, "--no-range");
  const HttpByteStore s(server.url(), quick());
  const std::uint64_t whole = http_counters().whole_for_range;
  EXPECT_EQ(s.read_range("a/obj", 10, 20), bytes_of(content.substr(10, 20)));
  EXPECT_EQ(s.read_suffix("a/obj", 8), bytes_of(content.substr(992)));
  EXPECT_EQ(http_counters().whole_for_range - whole, 2u);
}

TEST(HttpByteStore, ForbiddenIsAPermanentErrorNamingTheUrl) {
  std::string content;
  const fs::path root = object_root(content);
  test::HttpTestServer server(root, "--deny obj");
  const HttpByteStore s(server.url(), quick());
  const std::uint64_t retries = http_counters().retries;
  try {
    s.read("a/obj", kMaxChunkObjectBytes);
    FAIL() << "no error";
  } catch (const TransientError& e) {
    FAIL() << "transient: " << e.what();
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), server.url("a/obj") + ": HTTP 403 Forbidden");
  }
  EXPECT_EQ(http_counters().retries, retries);  // never retried
}

// Every request fails the one way `fault` names: tried `tries` times, then TransientError naming the URL.
void expect_transient(const std::string& fault, const std::string& expect_text, bool ranged) {
  SCOPED_TRACE(fault);
  std::string content;
  const fs::path root = object_root(content);
  test::HttpTestServer server(root, "--fault-rate 1 --stall 60 --faults " + fault);
  const HttpByteStore s(server.url(), quick(3, 1000));
  const std::uint64_t retries = http_counters().retries, failed = http_counters().failed;
  const auto t0 = std::chrono::steady_clock::now();
  try {
    if (ranged) s.read_range("a/obj", 0, 500);
    else s.read("a/obj", kMaxChunkObjectBytes);
    FAIL() << "no error";
  } catch (const TransientError& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind(server.url("a/obj") + ": ", 0), 0u) << what;
    EXPECT_NE(what.find(expect_text), std::string::npos) << what;
    EXPECT_NE(what.find("gave up after 3 tries"), std::string::npos) << what;
  }
  // Not a timing assertion: the server stalls 60 s per request, so a client waiting out a stall would
  // take minutes; three 1-second tries plus backoff finish far inside this bound.
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(30));
  EXPECT_EQ(http_counters().retries - retries, 2u);
  EXPECT_EQ(http_counters().failed - failed, 1u);
}

TEST(HttpByteStore, ServerErrorsAreRetriedThenTransient) { expect_transient("500", "HTTP 500", false); }
TEST(HttpByteStore, DroppedConnectionsAreRetriedThenTransient) { expect_transient("drop", "ransfer", false); }
TEST(HttpByteStore, TruncatedRangesAreRetriedThenTransient) {
  expect_transient("truncate", "truncated range answer (250 of 500 bytes)", true);
}
TEST(HttpByteStore, StallsTimeOutThenTransient) { expect_transient("stall", "imeout", false); }

TEST(HttpByteStore, FaultsAtARateAreHiddenByRetries) {
  std::string content;
  const fs::path root = object_root(content);
  test::HttpTestServer server(root, "--fault-rate 0.3 --seed 7 --faults 500,drop,truncate");
  const HttpByteStore s(server.url(), quick(8, 2000));
  const std::uint64_t retries = http_counters().retries;
  for (int i = 0; i < 40; ++i) EXPECT_EQ(s.read_range("a/obj", std::uint64_t(i), 100), bytes_of(content.substr(std::size_t(i), 100)));
  EXPECT_GT(http_counters().retries - retries, 0u);
}

TEST(StoreUrl, BadUrlsAreOneClearError) {
  const auto why = [](const std::string& spec) {
    try {
      zarr::open_store(spec);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(why("http://"), "http://: the URL has no host");
  EXPECT_EQ(why("ftp://example.org/s.zarr").rfind("ftp://example.org/s.zarr: unsupported URL scheme 'ftp'", 0), 0u);
  EXPECT_EQ(why("zarr://s3://bucket/x").rfind("zarr://s3://bucket/x: unsupported URL scheme 's3'", 0), 0u);
  EXPECT_EQ(why("http://h/x.zarr?a=1").rfind("http://h/x.zarr?a=1: a store URL takes no query", 0), 0u);
  setenv("SPARSELEAP_HTTP_TRIES", "2", 1);
  const std::string refused = why("http://127.0.0.1:1/x.zarr");
  unsetenv("SPARSELEAP_HTTP_TRIES");
  EXPECT_EQ(refused.rfind("http://127.0.0.1:1/x.zarr: ", 0), 0u) << refused;
  EXPECT_NE(refused.find("http://127.0.0.1:1/x.zarr/zarr.json"), std::string::npos) << refused;
  EXPECT_NE(refused.find("gave up after 2 tries"), std::string::npos) << refused;
  EXPECT_EQ(refused.find('\n'), std::string::npos);
}

TEST(StoreUrl, PrefixesAndRecognitionByContent) {
  EXPECT_TRUE(is_url("https://a/b"));
  EXPECT_TRUE(is_url("zarr3://https://a/b"));
  EXPECT_FALSE(is_url("/data/x.zarr"));
  EXPECT_FALSE(is_url("builtin:neurites"));
  const fs::path dir = test::scratch_dir();
  fs::create_directories(dir / "pc");
  test::write_text(dir / "pc" / "info", "{}");
  fs::create_directories(dir / "z2");
  test::write_text(dir / "z2" / ".zgroup", "{}");
  test::HttpTestServer server(dir);
  EXPECT_EQ(probe_store_kind(*open_url_store(server.url("pc")).bytes), StoreKind::Precomputed);
  EXPECT_EQ(probe_store_kind(*open_url_store(server.url("z2")).bytes), StoreKind::Zarr);
  EXPECT_EQ(probe_store_kind(*open_url_store(server.url("nothing")).bytes), StoreKind::None);
  EXPECT_EQ(open_url_store("precomputed://" + server.url("pc")).kind, StoreKind::Precomputed);
  EXPECT_EQ(open_url_store("zarr2://" + server.url("z2")).kind, StoreKind::Zarr);
  EXPECT_NE(recognise_url(server.url("pc")).kind, StoreKind::Zarr);
  EXPECT_EQ(recognise_url(server.url("z2")).kind, StoreKind::Zarr);
  EXPECT_EQ(recognise_url(server.url("pc")).kind, StoreKind::Precomputed);
  EXPECT_EQ(recognise_url("precomputed://" + server.url("pc")).path, server.url("pc"));
  EXPECT_EQ(recognise_url(server.url("nothing")).kind, StoreKind::Zarr);  // the Zarr reader names what is missing
  // store_kind.h's recognise_store takes URLs as local paths.
  EXPECT_EQ(recognise_store(server.url("pc")).kind, StoreKind::Precomputed);
  EXPECT_EQ(recognise_store("zarr://" + server.url("z2")).path, server.url("z2"));
  EXPECT_EQ(recognise_store((dir / "pc").string()).kind, StoreKind::Precomputed);
  EXPECT_EQ(recognise_store((dir / "z2").string()).kind, StoreKind::Zarr);
  // A local directory behind a prefix.
  EXPECT_EQ(probe_store_kind(*open_url_store("precomputed://" + (dir / "pc").string()).bytes), StoreKind::Precomputed);
}

// Every brick of `url` equals the same brick of `local` (image and labels, every level).
void expect_same_bricks(const ZarrVolumeSource& local, const ZarrVolumeSource& remote, int brick) {
  ASSERT_EQ(local.desc().dims, remote.desc().dims);
  ASSERT_EQ(local.has_labels(), remote.has_labels());
  const BrickLayout layout = BrickLayout::make(local.desc(), brick);
  const std::size_t n = std::size_t(layout.stored_voxels());
  std::vector<std::byte> a(n * std::size_t(voxel_size(local.desc().type))), b(a.size());
  std::vector<std::byte> la(local.has_labels() ? n * std::size_t(voxel_size(local.label_type())) : 0), lb(la.size());
  int bad = 0;
  for (int l = 0; l < layout.levels; ++l) {
    const ivec3 nb = layout.bricks(l);
    for (int z = 0; z < nb.z; ++z)
      for (int y = 0; y < nb.y; ++y)
        for (int x = 0; x < nb.x; ++x) {
          const BrickId id = BrickId::pack(l, ivec3(x, y, z));
          local.read_brick(layout, id, a, la);
          remote.read_brick(layout, id, b, lb);
          if ((a != b || la != lb) && ++bad <= 3) ADD_FAILURE() << "brick " << to_string(id) << " differs";
        }
  }
}

class ZarrFormatOverHttp : public ::testing::TestWithParam<std::string> {};

std::string format_name(const ::testing::TestParamInfo<std::string>& info) {
  static const char* names[] = {"v2", "v3", "v3_sharded"};
  return names[info.index];
}

TEST_P(ZarrFormatOverHttp, VoxelForVoxelAsLocal) {
  const fs::path dir = test::scratch_dir();
  ASSERT_EQ(test::run_sparseleap("gen neurites --dims 40x36x28 --out " + (dir / "v.nrrd").string()).exit_code, 0);
  const auto r = test::run_sparseleap("ingest " + (dir / "v.nrrd").string() + " " + (dir / "s.zarr").string() +
                                      " --labels " + (dir / "v_labels.nrrd").string() + " " + GetParam());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  test::HttpTestServer server(dir);
  const ZarrVolumeSource local((dir / "s.zarr").string());
  const ZarrVolumeSource remote(server.url("s.zarr"));
  EXPECT_EQ(remote.name(), server.url("s.zarr"));
  EXPECT_EQ(remote.max_label(), local.max_label());
  expect_same_bricks(local, remote, 16);
  // In core too: the whole level 0 read through HTTP.
  EXPECT_EQ(0, std::memcmp(read_zarr_volume(server.url("s.zarr")).data(), read_zarr_volume((dir / "s.zarr").string()).data(),
                           local.desc().byte_size()));
}

INSTANTIATE_TEST_SUITE_P(Formats, ZarrFormatOverHttp,
                         ::testing::Values("--chunk 8", "--chunk 8 --format zarr3", "--chunk 8 --format zarr3 --shard 2"),
                         format_name);

TEST(ZarrOverHttp, ZarrPython3StoresWithShardIndexAtStartAndEnd) {
  SL_REQUIRE_PEER3();
  for (const std::string index : {"start", "end"}) {
    SCOPED_TRACE(index);
    const fs::path dir = test::scratch_dir() / index;
    fs::create_directories(dir);
    std::string out;
    ASSERT_EQ(test::run_peer3("make " + (dir / "p.zarr").string() + " " + (dir / "expected").string() +
                                  " --dtype uint16 --shape 20,30,40 --chunks 10,10,10 --shards 20,20,20 --index " + index +
                                  " --compressor zstd --holes --missing --labels",
                              &out),
              0)
        << out;
    test::HttpTestServer server(dir);
    const ZarrVolumeSource src(server.url("p.zarr"));
    test::expect_bricks_match(src, dir / "expected", 3, 16, false);
    test::expect_bricks_match(src, dir / "expected", 3, 16, true);
    // Shards are read by range: an index (suffix or prefix range), then inner chunks.
    int ranges = 0;
    for (const std::string& l : server.log()) ranges += l.find(" bytes=") != std::string::npos;
    EXPECT_GT(ranges, 0);
  }
}

TEST(ZarrOverHttp, MissingChunksReadAsFillAndAreAskedForOnce) {
  const fs::path dir = test::scratch_dir();
  ASSERT_EQ(test::run_sparseleap("gen sphere --dims 32x32x32 --out " + (dir / "v.nrrd").string()).exit_code, 0);
  ASSERT_EQ(test::run_sparseleap("ingest " + (dir / "v.nrrd").string() + " " + (dir / "s.zarr").string() + " --chunk 8")
                .exit_code,
            0);
  fs::remove(dir / "s.zarr" / "0" / "0" / "0" / "0");  // a chunk never written (dimension_separator '/')
  test::HttpTestServer server(dir);
  const ZarrVolumeSource local((dir / "s.zarr").string()), remote(server.url("s.zarr"));
  expect_same_bricks(local, remote, 8);
  int asked = 0;
  for (const std::string& l : server.log()) asked += l.rfind("GET /s.zarr/0/0/0/0 ", 0) == 0;
  EXPECT_EQ(asked, 1);
}

TEST(ZarrOverHttp, MetadataNotFoundOrForbiddenIsOneLineNamingTheUrl) {
  const fs::path dir = test::scratch_dir();
  ASSERT_EQ(test::run_sparseleap("gen sphere --dims 16x16x16 --out " + (dir / "v.nrrd").string()).exit_code, 0);
  ASSERT_EQ(test::run_sparseleap("ingest " + (dir / "v.nrrd").string() + " " + (dir / "s.zarr").string()).exit_code, 0);
  {
    test::HttpTestServer server(dir);
    try {
      zarr::open_store(server.url("gone.zarr"));
      FAIL() << "no error";
    } catch (const InputError& e) {
      EXPECT_EQ(std::string(e.what()), server.url("gone.zarr") +
                                           ": no OME-Zarr multiscales in .zattrs and no .zarray: not an image store");
    }
  }
  test::HttpTestServer server(dir, "--deny .zarray");
  try {
    zarr::open_store(server.url("s.zarr"));
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), server.url("s.zarr") + ": level 0 (array '0'): cannot read '.zarray' (" +
                                         server.url("s.zarr/0/.zarray") + ": HTTP 403 Forbidden)");
  }
}

// Whole reads carry their caller's bound: an announced length past it is refused before the body is
// read, a body streamed past it is cut off, and a key that could leave the base is refused before any
// request.
TEST(HttpByteStore, WholeReadsAreBoundedAndKeysStayBelowTheBase) {
  std::string content;
  const fs::path root = object_root(content);
  test::HttpTestServer server(root, "--hostile");
  const HttpByteStore s(server.url(), quick(1));
  const auto error = [&](const std::string& key, std::uint64_t bound) {
    try {
      s.read(key, bound);
    } catch (const TransientError& e) {
      return std::string("transient: ") + e.what();
    } catch (const InputError& e) {
      return std::string(e.what());
    } catch (const std::runtime_error& e) {
      return std::string("runtime: ") + e.what();
    }
    return std::string("(no error)");
  };
  EXPECT_EQ(s.read("a/obj", 1000), bytes_of(content));
  EXPECT_EQ(error("a/obj", 999), server.url("a/obj") + ": the answer announces 1000 bytes, over the 999 bytes bound for this read");
  EXPECT_NE(error("hostile-huge-length", kMaxMetadataBytes)
                .find("announces 68719476736 bytes (65536 MiB), over the 67108864 bytes (64 MiB) bound"),
            std::string::npos);
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_EQ(error("hostile-endless", 1 << 20),
            server.url("hostile-endless") + ": the answer holds more than the 1048576 bytes (1 MiB) bound for this read");
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(10));
  const std::uint64_t before = http_counters().requests;
  for (const char* key : {"../a/obj", "%2e%2e/a/obj", "a/%2E%2E/%2e%2e/x", "a\\..\\..\\x", "/etc/passwd"}) {
    EXPECT_EQ(error(key, 1000).rfind("runtime: key '", 0), 0u) << key;
  }
  EXPECT_EQ(http_counters().requests, before);  // refused without a request
}

}  // namespace
}  // namespace sl
