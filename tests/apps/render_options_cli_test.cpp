// The render options render, bench and view share (apps/render_options.h): every command accepts the
// same flags and rejects the same bad values with the same one line and exit code. `view` runs without
// a display here: its checks all come before a window would open, and accepted options end at
// "cannot open a window".
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <nlohmann/json.hpp>

#include <array>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "tests/test_util.h"

namespace sl {
namespace {

namespace fs = std::filesystem;

const std::string kSmall = "--volume builtin:neurites:32x32x32 --size 16x12 --backend cpu";

// Runs `sparseleap CMD ARGS` with no display (so `view` never opens a window).
test::RunResult run(const std::string& cmd, const std::string& args) {
  return test::run_shell("env -u DISPLAY -u WAYLAND_DISPLAY " + test::sparseleap_exe().string() + " " + cmd + " " +
                         args + " 2>&1");
}

// kSmall's volume and size unless `args` gives its own.
std::string small(const std::string& args) {
  std::string s = "--backend cpu";
  if (args.find("--volume") == std::string::npos) s += " --volume builtin:neurites:32x32x32";
  if (args.find("--size") == std::string::npos) s += " --size 16x12";
  return s + " " + args;
}

bool no_viewer(const test::RunResult& r) { return r.output.find("this build has no viewer") != std::string::npos; }

// The extra arguments a command needs to run quickly and write nothing outside the scratch folder.
std::string extra(const std::string& cmd, const fs::path& dir) {
  if (cmd == "render") return " --out " + (dir / "r").string();
  if (cmd == "bench") return " --orbit 1 --warmup 0 --max-frames-per-view 3";
  return " --frames 1";
}

// Every command fails with exactly `line` (and the exit code) for `args`.
void expect_same_error(const std::string& args, const std::string& line, int code = 1) {
  const fs::path dir = test::scratch_dir();
  for (const std::string cmd : {"render", "bench", "view"}) {
    const test::RunResult r = run(cmd, small(args) + extra(cmd, dir));
    if (cmd == "view" && no_viewer(r)) continue;
    EXPECT_EQ(r.exit_code, code) << cmd << " " << args << ": " << r.output;
    EXPECT_EQ(r.output, line + "\n") << cmd << " " << args;
  }
  EXPECT_FALSE(fs::exists(dir / "r.png"));
}

TEST(RenderOptions, LodBiasMustBePositiveEverywhere) {
  expect_same_error("--lod-bias 0", "sparseleap: error: --lod-bias: must be positive");
  expect_same_error("--cache-mb 8 --lod-bias 0", "sparseleap: error: --lod-bias: must be positive");
  expect_same_error("--cache-mb 8 --lod-bias -1", "sparseleap: error: --lod-bias: must be positive");
}

TEST(RenderOptions, UploadBudgetMustNotBeNegativeEverywhere) {
  expect_same_error("--cache-mb 8 --upload-budget -1",
                    "sparseleap: error: --upload-budget: must be 0 (every loaded brick) or a number of bricks");
}

TEST(RenderOptions, LabelsModeNeedsLabelsAndOutOfCoreTheEnabledSet) {
  expect_same_error("--volume builtin:sphere:16x16x16 --mode labels",
                    "sparseleap: error: --mode: labels mode needs a label volume (--labels)");
  expect_same_error("--volume procedural:neurites:64x64x64 --mode labels",
                    "sparseleap: error: --mode: labels mode needs a label volume (--labels)");
  expect_same_error("--cache-mb 8 --mode labels",
                    "sparseleap: error: --mode: labels mode out of core needs --enable (the set of labels to show)");
}

TEST(RenderOptions, OutOfCoreMethodsAreSparseLeapAndNone) {
  const std::string line = "sparseleap: error: --method: out-of-core rendering supports sparseleap and none";
  for (const std::string cmd : {"render", "view"}) {
    const test::RunResult r = run(cmd, kSmall + " --cache-mb 8 --method octree" + extra(cmd, test::scratch_dir()));
    if (cmd == "view" && no_viewer(r)) continue;
    EXPECT_EQ(r.exit_code, 1) << cmd;
    EXPECT_EQ(r.output, line + "\n") << cmd;
  }
  const test::RunResult b = run("bench", kSmall + " --cache-mb 8 --methods none,bbox --orbit 1");
  EXPECT_EQ(b.exit_code, 1);
  EXPECT_EQ(b.output, "sparseleap: error: --methods: out-of-core rendering supports sparseleap and none\n");
}

TEST(RenderOptions, SharedValuesAreCheckedTheSameWay) {
  expect_same_error("--step 0", "sparseleap: error: --step: step must be in [0.001, 64]");
  expect_same_error("--threads -1", "sparseleap: error: --threads: must be 0 (all cores) or a number of threads");
  expect_same_error("--lists vulkan", "sparseleap: error: --lists: unknown list builder 'vulkan' (expected cpu or gl)");
  expect_same_error("--lod -2", "sparseleap: error: --lod: must be a level (0: full resolution)");
  expect_same_error("--size 0x4", "sparseleap: error: --size: width and height must be between 1 and 16384");
  expect_same_error("--mode xray", "sparseleap: error: --mode: unknown mode 'xray' (expected dvr, mip, iso or labels)");
  expect_same_error("--cuda-sampler tex",
                    "sparseleap: error: --cuda-sampler: unknown sampler 'tex' (expected slots or atlas)");
  expect_same_error("--cache-mb 8 --lod 9", "sparseleap: error: --lod: level 9 does not exist (the volume has 1 levels)");
  expect_same_error("--block 12", "sparseleap: error: --block: culling block size must be auto, 4, 8, 16 or 32 (got '12')");
  expect_same_error("--block 8x", "sparseleap: error: --block: culling block size must be auto, 4, 8, 16 or 32 (got '8x')");
}

// `column` of the last row of a bench run's CSV over one view.
long bench_column(const std::string& args, const std::string& column) {
  const fs::path csv = test::scratch_dir() / "block.csv";
  const test::RunResult r = run("bench", small("--volume builtin:neurites:64x64x64 --methods sparseleap --orbit 1 "
                                               "--warmup 0 --max-frames-per-view 30 --csv " + csv.string() + " " + args));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  FILE* f = std::fopen(csv.string().c_str(), "r");
  if (!f) return -1;
  auto split = [](const char* text) {
    std::vector<std::string> v(1);
    for (const char* c = text; *c && *c != '\n'; ++c) {
      if (*c == ',') {
        v.emplace_back();
      } else {
        v.back() += *c;
      }
    }
    return v;
  };
  char line[4096];
  std::vector<std::string> header, row;
  if (std::fgets(line, sizeof line, f)) header = split(line);
  while (std::fgets(line, sizeof line, f)) row = split(line);
  std::fclose(f);
  for (std::size_t i = 0; i < header.size() && i < row.size(); ++i) {
    if (header[i] == column) return std::stol(row[i]);
  }
  return -1;
}

TEST(RenderOptions, BlockAutoIsEightInCoreAndSixteenOutOfCore) {
  const long in_auto = bench_column("", "boxes"), in8 = bench_column("--block 8", "boxes"),
             in16 = bench_column("--block 16", "boxes");
  EXPECT_GT(in8, 0);
  EXPECT_NE(in8, in16);  // the block does decide the boxes here
  EXPECT_EQ(in_auto, in8);
  // Out of core, auto is 16: more than 8-voxel bricks hold, as --block 16 is (and --block 8 is not).
  expect_same_error("--cache-mb 16 --brick 8",
                    "sparseleap: error: --block: the culling block must not exceed the brick size (--brick)");
  expect_same_error("--cache-mb 16 --brick 8 --block 16",
                    "sparseleap: error: --block: the culling block must not exceed the brick size (--brick)");
  EXPECT_GT(bench_column("--cache-mb 16 --brick 8 --block 8", "samples"), 0);
}

TEST(RenderOptions, TheTextureAtlasIsOnlyForTheCudaBackendOutOfCore) {
  const fs::path dir = test::scratch_dir();
  const test::RunResult r = run("render", kSmall + " --cuda-sampler atlas --out " + (dir / "a").string());
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("sparseleap: error: --cuda-sampler: atlas"), std::string::npos) << r.output;
  const test::RunResult c =
      run("render", "--volume builtin:neurites:32x32x32 --size 8x8 --backend cpu --cache-mb 8 --cuda-sampler atlas "
                    "--out " + (dir / "a").string());
  EXPECT_EQ(c.exit_code, 1) << c.output;
  EXPECT_NE(c.output.find("--cuda-sampler: atlas"), std::string::npos) << c.output;
  const test::RunResult s = run("render", kSmall + " --cache-mb 8 --cuda-sampler slots --out " + (dir / "s").string());
  EXPECT_EQ(s.exit_code, 0) << s.output;
}

TEST(RenderOptions, CommandLineSyntaxErrorsExitTwoEverywhere) {
  for (const std::string cmd : {"render", "bench", "view"}) {
    const test::RunResult r = run(cmd, "--no-such-flag");
    if (cmd == "view" && no_viewer(r)) continue;
    EXPECT_EQ(r.exit_code, 2) << cmd << ": " << r.output;
    EXPECT_EQ(r.output.rfind("sparseleap: ", 0), 0u) << r.output;
    const test::RunResult t = run(cmd, "--lod-bias many");
    EXPECT_EQ(t.exit_code, 2) << cmd << ": " << t.output;
  }
}

TEST(RenderOptions, EveryCommandAcceptsTheSharedFlags) {
  const fs::path dir = test::scratch_dir();
  const std::string shared =
      " --cache-mb 8 --brick 16 --block 8 --lod 0 --lod-bias 2 --retire-frames 5 --lists cpu --cuda-sampler slots "
      "--threads 1 --step 0.75 --ert --iso 90 --enable all --tf " +
      (dir / "tf.json").string();
  test::write_text(dir / "tf.json", R"({"points":[{"value":0,"rgba":[0,0,0,0]},{"value":255,"rgba":[1,1,1,1]}]})");
  const test::RunResult r = run("render", kSmall + shared + " --method none --view depth-complexity --boxes --out " +
                                              (dir / "r").string());
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(dir / "r.png"));
  const test::RunResult b = run("bench", kSmall + shared + " --orbit 1 --max-frames-per-view 3");
  EXPECT_EQ(b.exit_code, 0) << b.output;
  const test::RunResult v = run("view", kSmall + shared + " --method none --view depth-complexity --boxes --frames 1");
  if (!no_viewer(v)) {
    // Every option was accepted and checked; only the display is missing.
    EXPECT_EQ(v.exit_code, 1) << v.output;
    EXPECT_NE(v.output.find("cannot open a window"), std::string::npos) << v.output;
  }
}

TEST(RenderOptions, BenchOutOfCoreHonoursMethodsAndWarmup) {
  const fs::path dir = test::scratch_dir();
  const std::string common = kSmall + " --cache-mb 8 --brick 16 --orbit 2 --max-frames-per-view 5";
  test::RunResult r = run("bench", common + " --methods none,sparseleap --json " + (dir / "b.json").string() +
                                       " --csv " + (dir / "b.csv").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string j = test::read_text(dir / "b.json");
  EXPECT_NE(j.find("\"none\""), std::string::npos) << j;
  EXPECT_NE(j.find("\"sparseleap\""), std::string::npos) << j;
  const std::string csv = test::read_text(dir / "b.csv");
  EXPECT_EQ(csv.rfind("method,view,frame,", 0), 0u) << csv;
  EXPECT_NE(csv.find("\nnone,0,1,"), std::string::npos) << csv;
  EXPECT_NE(csv.find("\nsparseleap,0,1,"), std::string::npos) << csv;
  // Without --methods out of core: sparseleap only (the in-core list has methods it cannot render).
  r = run("bench", common + " --json " + (dir / "d.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(test::read_text(dir / "d.json").find("\"none\""), std::string::npos);
  // Cold, the first view's first frame finds no brick resident; after 100 warm-up frames on that view
  // (a few small bricks from memory load long before), it finds some.
  r = run("bench", common + " --warmup 0 --json " + (dir / "cold.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = run("bench", common + " --warmup 100 --json " + (dir / "warm.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto first_hit_rate = [](const fs::path& file) {
    const nlohmann::json js = nlohmann::json::parse(test::read_text(file));
    return js["methods"]["sparseleap"]["views"][0]["first_frame_hit_rate"].get<double>();
  };
  EXPECT_EQ(first_hit_rate(dir / "cold.json"), 0.0);
  EXPECT_GT(first_hit_rate(dir / "warm.json"), 0.0);
  r = run("bench", common + " --warmup 101");
  EXPECT_EQ(r.output, "sparseleap: error: --warmup: must be between 0 and 100\n");
}

TEST(RenderOptions, BenchRejectsAnEmptyOrbitInAndOutOfCore) {
  for (const std::string where : {"", " --cache-mb 8"}) {
    const test::RunResult r = run("bench", kSmall + where + " --orbit 0");
    EXPECT_EQ(r.exit_code, 1) << where;
    EXPECT_EQ(r.output, "sparseleap: error: --orbit: must be between 1 and 100000\n") << where;
  }
}

TEST(RenderOptions, InjectFaultsSpecsAreCheckedEverywhere) {
  expect_same_error("--cache-mb 8 --inject-faults permanent=2",
                    "sparseleap: --inject-faults: permanent must be a share in [0, 1], got '2'", 2);
  expect_same_error("--cache-mb 8 --inject-faults bogus=1",
                    "sparseleap: --inject-faults: unknown key 'bogus' (expected permanent, transient, short, recover, "
                    "delay, delay-ms, seed)", 2);
  expect_same_error("--inject-faults transient=0.1",
                    "sparseleap: error: --inject-faults: faults are injected into out-of-core brick reads: add --cache-mb");
}

TEST(RenderOptions, InjectedFaultsAreCountedInTheSummaryAndStats) {
  const fs::path dir = test::scratch_dir();
  const test::RunResult r =
      run("render", small("--size 32x32 --cache-mb 16 --brick 8 --block 8 --lod 0 --frames 30 --allow-partial --inject-faults "
                          "permanent=0.2,transient=0.2,seed=3 --out " + (dir / "f").string() + " --stats-json " +
                          (dir / "f.json").string()));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const nlohmann::json c = nlohmann::json::parse(test::read_text(dir / "f.json"))["cache"];
  EXPECT_GT(c["failed"].get<int>(), 0) << r.output;
  EXPECT_GT(c["bricks_retried"].get<int>(), 0) << r.output;
  EXPECT_GE(c["retries"].get<int>(), c["bricks_retried"].get<int>());
  EXPECT_LE(c["recovered"].get<int>(), c["bricks_retried"].get<int>());
  EXPECT_NE(r.output.find(std::to_string(c["failed"].get<int>()) + " bricks failed, " +
                          std::to_string(c["bricks_retried"].get<int>()) + " retried ("),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("injected read error in level 0 brick ("), std::string::npos) << r.output;
}

}  // namespace
}  // namespace sl
