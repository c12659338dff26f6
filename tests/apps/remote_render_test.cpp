// `render` of OME-Zarr stores over HTTP, against the tests' own server on 127.0.0.1
// (tests/data_tools/http_server.py): the same PNG as from the local directory (Zarr v2, v3 sharded),
// with the remote summary line; --disk-cache serves a second run without chunk requests; under a
// fault server (500s, dropped connections, truncated ranges, stalls) the render completes, retries are
// counted and a brick that fails for good is reported once and rendered as missing; bad URLs are one
// clear error line.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <regex>
#include <set>

#include "tests/http_test_server.h"
#include "tests/test_util.h"

namespace sl {
namespace {

namespace fs = std::filesystem;

// A labelled neurites store at dir/NAME written by `ingest FLAGS`.
void make_store(const fs::path& dir, const std::string& name, const std::string& flags) {
  if (!fs::exists(dir / "v.nrrd")) {
    ASSERT_EQ(test::run_sparseleap("gen neurites --dims 64x64x64 --out " + (dir / "v.nrrd").string()).exit_code, 0);
  }
  const auto r = test::run_sparseleap("ingest " + (dir / "v.nrrd").string() + " " + (dir / name).string() +
                                      " --labels " + (dir / "v_labels.nrrd").string() + " " + flags);
  ASSERT_EQ(r.exit_code, 0) << r.output;
}

// `env sparseleap render --volume VOLUME ...` into dir/OUT.png.
test::RunResult render(const fs::path& dir, const std::string& volume, const std::string& out,
                       const std::string& env = "", const std::string& extra = "", int frames = 40,
                       const std::string& size = "96x96") {
  return test::run_shell(env + " " + test::sparseleap_exe().string() + " render --volume " + volume +
                         " --cache-mb 64 --frames " + std::to_string(frames) + " --size " + size + " --out " +
                         (dir / out).string() + " " + extra + " 2>&1");
}

std::uint64_t number_before(const std::string& text, const std::string& what) {
  std::smatch m;
  if (!std::regex_search(text, m, std::regex("([0-9]+) " + what))) return ~std::uint64_t(0);
  return std::stoull(m[1]);
}

TEST(RemoteRender, SameImageAsLocalForV2AndV3Sharded) {
  const fs::path dir = test::scratch_dir();
  make_store(dir, "v2.zarr", "--chunk 16");
  make_store(dir, "v3.zarr", "--chunk 8 --format zarr3 --shard 4");
  test::HttpTestServer server(dir);
  for (const std::string name : {"v2", "v3"}) {
    SCOPED_TRACE(name);
    const auto local = render(dir, (dir / (name + ".zarr")).string(), name + "_local");
    ASSERT_EQ(local.exit_code, 0) << local.output;
    EXPECT_EQ(local.output.find("remote:"), std::string::npos) << local.output;
    const auto remote = render(dir, server.url(name + ".zarr"), name + "_http");
    ASSERT_EQ(remote.exit_code, 0) << remote.output;
    EXPECT_NE(remote.output.find("completeness 1.000"), std::string::npos) << remote.output;
    EXPECT_GT(number_before(remote.output, "requests"), 0u) << remote.output;
    EXPECT_EQ(number_before(remote.output, "retried"), 0u) << remote.output;
    EXPECT_EQ(test::read_text(dir / (name + "_local.png")), test::read_text(dir / (name + "_http.png")));
  }
  // The prefixed form, and in core (no --cache-mb) through the same reader.
  const auto prefixed = test::run_sparseleap("render --volume zarr3://" + server.url("v3.zarr") +
                                             " --size 96x96 --out " + (dir / "v3_core").string());
  ASSERT_EQ(prefixed.exit_code, 0) << prefixed.output;
  const auto core = test::run_sparseleap("render --volume " + (dir / "v3.zarr").string() + " --size 96x96 --out " +
                                         (dir / "v3_core_local").string());
  ASSERT_EQ(core.exit_code, 0) << core.output;
  EXPECT_EQ(test::read_text(dir / "v3_core.png"), test::read_text(dir / "v3_core_local.png"));
}

TEST(RemoteRender, DiskCacheServesTheSecondRun) {
  const fs::path dir = test::scratch_dir();
  make_store(dir, "v3.zarr", "--chunk 8 --format zarr3 --shard 4");
  test::HttpTestServer server(dir);
  const std::string cache = "--disk-cache " + (dir / "dc").string() + " --disk-cache-mb 64";
  const auto first = render(dir, server.url("v3.zarr"), "first", "", cache);
  ASSERT_EQ(first.exit_code, 0) << first.output;
  const std::size_t after_first = server.log().size();
  const auto second = render(dir, server.url("v3.zarr"), "second", "", cache);
  ASSERT_EQ(second.exit_code, 0) << second.output;
  EXPECT_EQ(test::read_text(dir / "first.png"), test::read_text(dir / "second.png"));
  // The first run's hits are few: the store probe's objects read again by the open, and a chunk that
  // a second brick's apron reads after the chunk cache let it go (how many depends on the loader
  // threads' timing).
  std::smatch m;
  ASSERT_TRUE(std::regex_search(first.output, m, std::regex("disk cache ([0-9]+) hits, ([0-9]+) misses"))) << first.output;
  EXPECT_LT(std::stoull(m[1]) * 10, std::stoull(m[2])) << first.output;
  EXPECT_GT(number_before(second.output, "hits"), 100u) << second.output;
  // The second run asks only for objects that do not exist (404s are not cached): no shard request.
  const std::vector<std::string> log = server.log();
  for (std::size_t i = after_first; i < log.size(); ++i) EXPECT_NE(log[i].find(" 404 "), std::string::npos) << log[i];
  EXPECT_LT(log.size() - after_first, after_first / 4);
}

TEST(RemoteRender, FaultServerRenderCompletesWithRetriesAndOneReportPerFailedBrick) {
  const fs::path dir = test::scratch_dir();
  make_store(dir, "v2.zarr", "--chunk 16");
  // Faults only on chunks (metadata stays reachable); chunk 0/1/1/1 of level 0 fails for good.
  test::HttpTestServer server(dir, "--fault-rate 0.2 --seed 3 --stall 30 --fault-paths /0/ --fail-always /0/1/1/1");
  // Level 0 pinned, so a small image still needs every brick. Between frames render waits for the
  // loads in flight, stalled (0.3 s) and retried ones included: the client tries twice per read, the
  // loader five times with backoff (50-400 ms), about 2 s before a chunk that always fails is given up.
  const auto r = render(dir, server.url("v2.zarr"), "faulty", "SPARSELEAP_HTTP_TIMEOUT=0.3 SPARSELEAP_HTTP_TRIES=2", "--lod 0",
                        400, "32x32");
  // The image is written, short of the bricks that failed: partial.
  ASSERT_EQ(r.exit_code, 4) << r.output;
  EXPECT_NE(r.output.find("bricks failed to load after 400 frames"), std::string::npos) << r.output;
  EXPECT_GT(number_before(r.output, "retried"), 0u) << r.output;
  EXPECT_GT(number_before(r.output, "failed after retries"), 0u) << r.output;
  // Each failed brick is reported once, naming the URL of the chunk and the status.
  std::smatch m;
  std::string rest = r.output;
  std::size_t reports = 0;
  std::set<std::string> bricks;
  const std::regex warn("brick failed to load, rendered as missing: ([^\n]*)");
  while (std::regex_search(rest, m, warn)) {
    ++reports;
    EXPECT_TRUE(bricks.insert(m[1]).second) << "reported twice: " << m[1];
    EXPECT_NE(m[1].str().find(server.url("v2.zarr/0/1/1/1")), std::string::npos) << m[1];
    EXPECT_NE(m[1].str().find("HTTP 500"), std::string::npos) << m[1];
    rest = m.suffix();
  }
  EXPECT_GT(reports, 0u) << r.output;
  EXPECT_NE(r.output.find("completeness"), std::string::npos) << r.output;
}

TEST(RemoteRender, BadUrlsAreOneErrorLine) {
  const fs::path dir = test::scratch_dir();
  for (const auto& [url, text] : std::vector<std::pair<std::string, std::string>>{
           {"http://", "sparseleap: error: http://: the URL has no host"},
           {"ftp://example.org/s.zarr", "sparseleap: error: ftp://example.org/s.zarr: unsupported URL scheme 'ftp'"},
           {"http://127.0.0.1:1/x", "sparseleap: error: http://127.0.0.1:1/x: cannot probe the store ("
                                    "http://127.0.0.1:1/x/zarr.json: "}}) {
    SCOPED_TRACE(url);
    const auto r = render(dir, url, "bad", "SPARSELEAP_HTTP_TRIES=2");
    EXPECT_EQ(r.exit_code, 1) << r.output;
    EXPECT_EQ(r.output.rfind(text, 0), 0u) << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  }
  const auto env = render(dir, "http://127.0.0.1:1/x", "bad", "SPARSELEAP_HTTP_TIMEOUT=abc");
  EXPECT_EQ(env.output, "sparseleap: error: SPARSELEAP_HTTP_TIMEOUT: expected a number from 0.01 to 3600, got 'abc'\n");
  const auto mb = test::run_sparseleap("render --disk-cache-mb 10 --out " + (dir / "x").string());
  EXPECT_EQ(mb.output, "sparseleap: error: --disk-cache-mb: needs --disk-cache DIR\n");
}

}  // namespace
}  // namespace sl
