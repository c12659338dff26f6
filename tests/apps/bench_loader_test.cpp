// `bench --loader` (apps/bench/loader.h): the brick loader's throughput from a Zarr v3 sharded store
// read from its directory and over the tests' HTTP server (tests/data_tools/http_server.py), with and
// without --disk-cache; a corrupt shard is counted as failed bricks without stopping the run; bad
// option values are one line with exit 2. No timing is asserted (STYLE.md #11): only that every figure
// is there, every requested brick is accounted for, and the rates are positive.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "tests/http_test_server.h"
#include "tests/test_util.h"

namespace sl {
namespace {

namespace fs = std::filesystem;

// dir/v3.zarr: labelled neurites 64³ in zstd chunks of 8³, shards of 4³ chunks. Read with --brick 16,
// level 0 has 4 x 4 x 4 = 64 bricks.
constexpr int kLevel0Bricks = 64;

void make_store(const fs::path& dir) {
  ASSERT_EQ(test::run_sparseleap("gen neurites --dims 64x64x64 --out " + (dir / "v.nrrd").string()).exit_code, 0);
  const auto r = test::run_sparseleap("ingest " + (dir / "v.nrrd").string() + " " + (dir / "v3.zarr").string() +
                                      " --labels " + (dir / "v_labels.nrrd").string() +
                                      " --chunk 8 --format zarr3 --shard 4 --compressor zstd");
  ASSERT_EQ(r.exit_code, 0) << r.output;
}

// `sparseleap bench --loader` of `volume` (out of core: --cache-mb), stdout and stderr.
test::RunResult bench_loader(const std::string& volume, const std::string& extra) {
  return test::run_shell(test::sparseleap_exe().string() + " bench --backend cpu --cache-mb 16 --brick 16 --volume " +
                         volume + " --loader " + extra + " 2>&1");
}

nlohmann::json read_json(const fs::path& p) { return nlohmann::json::parse(test::read_text(p)); }

// The summary fields and per-pass arrays of a run that asked for `bricks` bricks per pass; returns
// the failures (most in a pass).
std::uint64_t expect_report(const nlohmann::json& j, std::uint64_t bricks, int passes) {
  for (const char* key : {"loader_bricks_per_s", "loader_mb_per_s", "loader_p50_ms", "loader_p95_ms", "loader_threads",
                          "loader_bricks", "loader_passes", "loader_failed", "volume", "loader_pass_bricks",
                          "loader_pass_failed", "loader_pass_bricks_per_s", "loader_pass_mb_per_s",
                          "loader_pass_p50_ms", "loader_pass_p95_ms"}) {
    EXPECT_TRUE(j.contains(key)) << key << " missing: " << j.dump();
  }
  if (!j.contains("loader_pass_bricks") || !j.contains("loader_pass_failed")) return 0;
  EXPECT_EQ(j["loader_bricks"].get<std::uint64_t>(), bricks);
  EXPECT_EQ(j["loader_passes"].get<int>(), passes);
  EXPECT_GE(j["loader_threads"].get<int>(), 1);
  EXPECT_GT(j["loader_bricks_per_s"].get<double>(), 0.0);
  EXPECT_GT(j["loader_mb_per_s"].get<double>(), 0.0);
  EXPECT_GE(j["loader_p95_ms"].get<double>(), j["loader_p50_ms"].get<double>());
  EXPECT_EQ(j["loader_pass_bricks"].size(), std::size_t(passes));
  EXPECT_EQ(j["loader_pass_p95_ms"].size(), std::size_t(passes));
  for (std::size_t p = 0; p < j["loader_pass_bricks"].size(); ++p) {
    // Every brick asked for is loaded or failed, once.
    EXPECT_EQ(j["loader_pass_bricks"][p].get<std::uint64_t>() + j["loader_pass_failed"][p].get<std::uint64_t>(), bricks)
        << "pass " << p + 1;
  }
  return j["loader_failed"].get<std::uint64_t>();
}

TEST(BenchLoader, LocalStoreLoadsTheRequestedBricks) {
  const fs::path dir = test::scratch_dir();
  make_store(dir);
  const auto r = bench_loader((dir / "v3.zarr").string(), "--loader-bricks 27 --loader-passes 2 --threads 2 --json " +
                                                              (dir / "l.json").string() + " --csv " +
                                                              (dir / "l.csv").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("median:"), std::string::npos) << r.output;
  const nlohmann::json j = read_json(dir / "l.json");
  EXPECT_EQ(expect_report(j, 27, 2), 0u) << r.output;
  EXPECT_EQ(j["loader_threads"].get<int>(), 2);
  // A header and a row per pass.
  const std::string csv = test::read_text(dir / "l.csv");
  EXPECT_EQ(csv.rfind("pass,bricks,failed,", 0), 0u) << csv;
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 3) << csv;
}

TEST(BenchLoader, HttpStoreLoadsEveryBrickOfASmallVolume) {
  const fs::path dir = test::scratch_dir();
  make_store(dir);
  test::HttpTestServer server(dir);
  // The default 4096 bricks are more than the volume has: all of them are loaded, and it says so.
  auto r = bench_loader(server.url("v3.zarr"), "--loader-passes 1 --json " + (dir / "h.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("the volume has only 64 level-0 bricks (--loader-bricks 4096): loading all of them"),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("remote: "), std::string::npos) << r.output;
  nlohmann::json j = read_json(dir / "h.json");
  EXPECT_EQ(expect_report(j, kLevel0Bricks, 1), 0u) << r.output;
  EXPECT_EQ(j["loader_bricks_requested"].get<int>(), 4096);
  // Through a disk cache: the first run fills it, the second reads it; both load every brick.
  const std::string cache = " --disk-cache " + (dir / "dc").string();
  for (const std::string run : {"fill", "read"}) {
    SCOPED_TRACE(run);
    r = bench_loader(server.url("v3.zarr"), "--loader-passes 2" + cache + " --json " + (dir / (run + ".json")).string());
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_EQ(expect_report(read_json(dir / (run + ".json")), kLevel0Bricks, 2), 0u) << r.output;
    EXPECT_NE(r.output.find("; disk cache "), std::string::npos) << r.output;
  }
}

TEST(BenchLoader, CorruptShardIsCountedAsFailedBricks) {
  const fs::path dir = test::scratch_dir();
  make_store(dir);
  // The largest level-0 shard (surely read): its first inner chunks overwritten, the index at its end
  // left intact, so the chunks are found and fail to decode.
  fs::path shard;
  for (const auto& e : fs::recursive_directory_iterator(dir / "v3.zarr" / "0" / "c")) {
    if (e.is_regular_file() && (shard.empty() || e.file_size() > fs::file_size(shard))) shard = e.path();
  }
  ASSERT_FALSE(shard.empty());
  ASSERT_GT(fs::file_size(shard), 300u);
  {
    std::fstream f(shard, std::ios::in | std::ios::out | std::ios::binary);
    const std::string junk(300, '\x42');
    f.write(junk.data(), std::streamsize(junk.size()));
  }
  const auto r = bench_loader((dir / "v3.zarr").string(), "--loader-passes 2 --json " + (dir / "c.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_GT(expect_report(read_json(dir / "c.json"), kLevel0Bricks, 2), 0u) << r.output;
  EXPECT_NE(r.output.find("first failure: "), std::string::npos) << r.output;
}

TEST(BenchLoader, BadOptionValuesAreOneLineWithExitTwo) {
  const std::string volume = "builtin:neurites:32x32x32";
  for (const auto& [args, line] : std::vector<std::pair<std::string, std::string>>{
           {"--cache-mb 8 --loader --loader-bricks 0",
            "sparseleap: --loader-bricks: must be a whole number from 1 to 10000000, not '0'"},
           {"--cache-mb 8 --loader --loader-bricks 10000001",
            "sparseleap: --loader-bricks: must be a whole number from 1 to 10000000, not '10000001'"},
           {"--cache-mb 8 --loader --loader-bricks many",
            "sparseleap: --loader-bricks: must be a whole number from 1 to 10000000, not 'many'"},
           {"--cache-mb 8 --loader --loader-passes 0",
            "sparseleap: --loader-passes: must be a whole number from 1 to 100, not '0'"},
           {"--cache-mb 8 --loader --loader-passes 101",
            "sparseleap: --loader-passes: must be a whole number from 1 to 100, not '101'"},
           {"--loader", "sparseleap: --loader: reads bricks out of core: add --cache-mb (or give a procedural volume)"},
       }) {
    SCOPED_TRACE(args);
    const auto r = test::run_shell(test::sparseleap_exe().string() + " bench --backend cpu --volume " + volume + " " +
                                   args + " 2>&1");
    EXPECT_EQ(r.exit_code, 2) << r.output;
    EXPECT_EQ(r.output, line + "\n");
  }
  // The loader's own options without --loader: one line naming the option, exit 2.
  const auto r = test::run_shell(test::sparseleap_exe().string() + " bench --backend cpu --volume " + volume +
                                 " --cache-mb 8 --loader-passes 2 2>&1");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_EQ(r.output.rfind("sparseleap: --loader-passes", 0), 0u) << r.output;
  EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
}

}  // namespace
}  // namespace sl
