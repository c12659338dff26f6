// `--distributed` under mpirun (DESIGN.md "Beyond one machine"): with 1, 2, 3 and 4 ranks the composited image equals
// the single-process out-of-core image (EXR RGBA within 1e-5, PNG within 1/255) for perspective and
// orthographic cameras, a camera inside the volume, ranks with empty regions, and a small cache per
// rank; bad input on one rank is one error line from rank 0 and every rank exits; a corrupt chunk is a
// data fault handled as one process handles it (rendered as missing with the same warning, exit 0;
// --strict exit 1 on every rank), never an exit or a hang of the job.
#include <unistd.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <nlohmann/json.hpp>
#include <regex>
#include <string>
#include <vector>

#include "cache/formats/nrrd/nrrd.h"
#include "core/scene/generate.h"
#include "core/util/image.h"
#include "tests/test_util.h"

namespace sl {
namespace {

std::string mpirun(int ranks) {
  // As root OpenMPI refuses to start without --allow-run-as-root; 2 cores need --oversubscribe.
  // `timeout`: a hang is a failure, not a stuck suite. Under AddressSanitizer (the ASan build) the
  // ranks run without leak checking: OpenMPI leaves allocations of its dlopened components at exit,
  // unsymbolized, which no suppression by library can name (the other suites keep leak checks).
  const char* asan = std::getenv("ASAN_OPTIONS");
  std::string cmd = asan ? "ASAN_OPTIONS=" + std::string(asan) + ":detect_leaks=0 " : std::string();
  cmd += "timeout 120 " SL_MPIEXEC " --oversubscribe -np " + std::to_string(ranks);
  if (::geteuid() == 0) cmd += " --allow-run-as-root";
  // OpenMPI's session directory under one of this test process's own, not the shared
  // /tmp/ompi.HOST.UID: ctest runs tests in parallel, and one mpirun removing that shared directory
  // while another creates its pid.N below it fails the second ("orte_session_dir failed").
  static const std::filesystem::path session = [] {
    const std::filesystem::path d =
        std::filesystem::path(SL_BINARY_DIR) / "test-scratch" / ("ompi-" + std::to_string(::getpid()));
    std::filesystem::create_directories(d);
    return d;
  }();
  cmd += " --mca orte_tmpdir_base " + session.string();
  return cmd;
}

struct Diff {
  float exr = 0.0f;  // largest |difference| of a premultiplied RGBA component
  float png = 0.0f;
};

Diff compare(const std::string& a, const std::string& b) {
  const Image ea = read_exr(a + ".exr"), eb = read_exr(b + ".exr");
  const Image pa = read_png(a + ".png"), pb = read_png(b + ".png");
  EXPECT_EQ(ea.width, eb.width);
  EXPECT_EQ(ea.height, eb.height);
  Diff d;
  for (std::size_t i = 0; i < std::min(ea.rgba.size(), eb.rgba.size()); ++i) {
    for (int c = 0; c < 4; ++c) {
      d.exr = std::max(d.exr, std::abs(ea.rgba[i][c] - eb.rgba[i][c]));
      d.png = std::max(d.png, std::abs(pa.rgba[i][c] - pb.rgba[i][c]));
    }
  }
  return d;
}

class Distributed : public ::testing::Test {
 protected:
  std::filesystem::path dir = test::scratch_dir();

  // Renders `args` in one process and with 1..4 ranks; every composite must equal the single image
  // (of the out-of-core renderer, which every rank runs: its level of detail follows the pixel
  // footprint, so the in-core image differs).
  void expect_same_image(const std::string& args) {
    const std::string exe = test::sparseleap_exe().string();
    const std::string single = (dir / "single").string();
    const std::string ooc = args.find("--cache-mb") == std::string::npos ? " --cache-mb 1024" : "";
    const test::RunResult s = test::run_shell(exe + " render " + args + ooc + " --out " + single + " 2>&1");
    ASSERT_EQ(s.exit_code, 0) << s.output;
    for (int ranks = 1; ranks <= 4; ++ranks) {
      const std::string out = (dir / ("ranks" + std::to_string(ranks))).string();
      const test::RunResult r = test::run_shell(mpirun(ranks) + " " + exe + " render --distributed " + args +
                                                " --out " + out + " --stats-json " + out + ".json 2>&1");
      ASSERT_EQ(r.exit_code, 0) << r.output;
      EXPECT_NE(r.output.find("distributed: " + std::to_string(ranks) + " ranks"), std::string::npos) << r.output;
      const std::string js = test::read_text(out + ".json");
      EXPECT_NE(js.find("\"composite_ms\""), std::string::npos);
      const Diff d = compare(single, out);
      EXPECT_LE(d.exr, 1e-5f) << ranks << " ranks";
      EXPECT_LE(d.png, 1.0f / 255.0f + 1e-6f) << ranks << " ranks";
    }
  }

  std::string camera(const std::string& json) {
    const std::string p = (dir / "camera.json").string();
    test::write_text(p, json);
    return " --camera " + p;
  }
};

// Bricks load asynchronously (a frame never waits): generous frame counts let every run converge, and
// --strict fails a run whose last frame is still incomplete, so a loaded machine cannot turn a
// half-loaded frame into a pixel difference.
constexpr const char* kVolume = " --volume builtin:neurites:96x80x64 --size 96x80 --frames 60 --strict";

TEST_F(Distributed, PerspectiveEqualsSingleProcess) { expect_same_image(kVolume); }

TEST_F(Distributed, OrthographicEqualsSingleProcess) {
  expect_same_image(std::string(kVolume) +
                    camera(R"({"eye":[150,-40,120],"center":[48,40,32],"projection":"orthographic","height":140})"));
}

TEST_F(Distributed, CameraInsideTheVolumeEqualsSingleProcess) {
  expect_same_image(std::string(kVolume) + camera(R"({"eye":[40,45,30],"center":[90,20,60],"fov_deg":70})"));
}

// One brick of 32³: 3 and 4 ranks give all but one rank an empty region (no samples at all).
TEST_F(Distributed, EmptyRegionsEqualSingleProcess) {
  expect_same_image(" --volume builtin:neurites:32x32x32 --brick 32 --size 64x64 --frames 100 --strict --method none");
}

// Out of core under a small cache per rank (the same budget single-process): bricks stream in over
// the frames and are evicted, and the converged composite is the same image.
TEST_F(Distributed, SmallCachePerRankEqualsSingleProcess) {
  expect_same_image(" --volume builtin:neurites:96x80x64 --brick 16 --cache-mb 1 --size 96x80 --frames 80 --strict");
}

// Without --frames, the single process and every rank render until complete (the ranks agree per
// frame that all have converged), so the composite is the converged image and the exit status 0.
TEST_F(Distributed, UntilCompleteWithoutFramesEqualsSingleProcess) {
  expect_same_image(" --volume builtin:neurites:96x80x64 --brick 16 --cache-mb 1 --size 96x80");
}

// Stopped short by --max-frames, rank 0 writes the composite of the last frames and exits 4 after one
// line; --allow-partial makes it 0.
TEST_F(Distributed, StoppedShortIsPartial) {
  const std::string exe = test::sparseleap_exe().string();
  const std::string out = (dir / "partial").string();
  const std::string args = " --volume builtin:neurites:96x80x64 --brick 16 --cache-mb 1 --size 96x80 --max-frames 1";
  test::RunResult r = test::run_shell(mpirun(2) + " " + exe + " render --distributed" + args + " --out " + out + " 2>&1");
  EXPECT_EQ(r.exit_code, 4) << r.output;
  EXPECT_TRUE(std::filesystem::exists(out + ".exr"));
  EXPECT_NE(r.output.find("sparseleap: incomplete image written to " + out + ".png"), std::string::npos) << r.output;
  r = test::run_shell(mpirun(2) + " " + exe + " render --distributed" + args + " --allow-partial --out " + out + " 2>&1");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("sparseleap: partial (--allow-partial) image written to "), std::string::npos) << r.output;
}

TEST_F(Distributed, IsoAndLabelsEqualSingleProcess) {
  expect_same_image(std::string(kVolume) + " --mode iso");
  expect_same_image(std::string(kVolume) + " --mode labels --enable all");
}

// --ert is per rank (apps/distributed.h): a rank stops at its own opacity 0.99, so the composite and
// the single process's terminated image each lie within the 1% of light the termination drops of
// the unterminated image, and within 1% of each other.
TEST_F(Distributed, EarlyRayTerminationIsWithinItsThresholdOfTheSingleProcess) {
  const std::string exe = test::sparseleap_exe().string();
  const std::string args = std::string(kVolume) + " --cache-mb 1024 --ert";
  const std::string single = (dir / "single").string(), out = (dir / "ert").string();
  const test::RunResult s = test::run_shell(exe + " render " + args + " --out " + single + " 2>&1");
  ASSERT_EQ(s.exit_code, 0) << s.output;
  const test::RunResult r = test::run_shell(mpirun(3) + " " + exe + " render --distributed " + args + " --out " + out + " 2>&1");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_LE(compare(single, out).exr, 0.01f + 1e-5f);
}

// bench --distributed: every frame composited; the views converge on every rank together and the
// JSON carries each view's distributed figures (per rank, compositing).
TEST_F(Distributed, BenchReportsEveryViewsDistributedFigures) {
  const std::string exe = test::sparseleap_exe().string();
  const std::string js = (dir / "bench.json").string();
  const test::RunResult r =
      test::run_shell(mpirun(2) + " " + exe + " bench --distributed --volume builtin:neurites:64x64x48 --size 48x40 " +
                      "--orbit 2 --max-frames-per-view 60 --json " + js + " 2>&1");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("0 views did not converge"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("distributed: 2 ranks"), std::string::npos) << r.output;
  const nlohmann::json j = nlohmann::json::parse(test::read_text(js));
  const auto& views = j["methods"]["sparseleap"]["views"];
  ASSERT_EQ(views.size(), 2u);
  for (const auto& v : views) {
    EXPECT_EQ(v["distributed"]["ranks"], 2);
    EXPECT_EQ(v["distributed"]["per_rank"].size(), 2u);
    EXPECT_GE(v["distributed"]["composite_ms"].get<double>(), 0.0);
  }
}

// Bad input on one rank (MPMD: rank 1 is given a missing file): rank 0 prints one error line naming
// the rank and the file, and every rank exits non-zero instead of waiting in a collective.
TEST_F(Distributed, BadInputOnOneRankIsOneErrorAndEveryRankExits) {
  const std::string exe = test::sparseleap_exe().string();
  const std::string out = (dir / "bad").string();
  std::string cmd = mpirun(1) + " " + exe + " render --distributed --size 32x32 --out " + out + " : -np 1 " + exe +
                    " render --distributed --size 32x32 --volume " + (dir / "missing.nrrd").string() + " --out " +
                    out + " : -np 1 " + exe + " render --distributed --size 32x32 --out " + out + " 2>&1";
  const test::RunResult r = test::run_shell(cmd);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.exit_code, 124) << "timed out: a rank hung\n" << r.output;  // timeout(1)'s code
  std::size_t lines = 0;
  for (std::size_t p = r.output.find("sparseleap: error:"); p != std::string::npos;
       p = r.output.find("sparseleap: error:", p + 1)) {
    ++lines;
  }
  EXPECT_EQ(lines, 1u) << r.output;
  EXPECT_NE(r.output.find("sparseleap: error: rank 1: "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("missing.nrrd"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(out + ".png"));
}

// A 32³ store of 8³ chunks with `corrupt(store)` applied: rendered once by one process and once by two
// ranks, out of core with 8³ bricks. Both must end with the same exit status, write an image, and print
// the same warning lines (a warning names the chunk and what is wrong with it). The work estimate
// that balances the ranks reads level 0 here, so it meets the corrupt chunk too.
class DistributedDataFault : public Distributed {
 protected:
  struct Run {
    test::RunResult result;
    std::vector<std::string> warnings, errors;
  };
  // The lines, sorted and unique, with the brick a warning names left out: the chunk and the fault
  // are the same in both runs, but which of the bricks that share the chunk reports it first depends
  // on the order the loader's threads (and the ranks' regions) reach them.
  static std::vector<std::string> lines_with(const std::string& text, const std::string& prefix) {
    static const std::regex brick(R"(brick \(\d+, \d+, \d+\))");
    std::vector<std::string> v;
    for (std::size_t p = text.find(prefix); p != std::string::npos; p = text.find(prefix, p + 1)) {
      v.push_back(std::regex_replace(text.substr(p, text.find('\n', p) - p), brick, "brick (.)"));
    }
    std::sort(v.begin(), v.end());
    v.erase(std::unique(v.begin(), v.end()), v.end());
    return v;
  }
  std::filesystem::path make_store(const std::function<void(const std::filesystem::path&)>& corrupt) {
    const GeneratedVolume g = generate_volume("blobs", ivec3(32), 1);
    write_nrrd((dir / "v.nrrd").string(), g.intensity);
    const std::filesystem::path store = dir / "s.zarr";
    const test::RunResult r = test::run_sparseleap("ingest " + (dir / "v.nrrd").string() + " " + store.string() +
                                                   " --chunk 8 --compressor zstd");
    EXPECT_EQ(r.exit_code, 0) << r.output;
    corrupt(store);
    return store;
  }
  Run render(const std::string& args, int ranks) {
    const std::string exe = test::sparseleap_exe().string();
    const std::string out = (dir / ("out" + std::to_string(ranks))).string();
    std::filesystem::remove(out + ".png");
    const std::string launch = ranks == 0 ? exe + " render " : mpirun(ranks) + " " + exe + " render --distributed ";
    Run run;
    run.result = test::run_shell(launch + args + " --out " + out + " 2>&1");
    run.warnings = lines_with(run.result.output, "sparseleap: warning:");
    run.errors = lines_with(run.result.output, "sparseleap: error:");
    EXPECT_NE(run.result.exit_code, 124) << "timed out: a rank hung\n" << run.result.output;
    if (run.result.exit_code == 0) EXPECT_TRUE(std::filesystem::exists(out + ".png")) << run.result.output;
    return run;
  }
  // The single process and two ranks agree; returns the single process's run.
  Run expect_like_single_process(const std::string& args) {
    const Run single = render(args, 0);
    const Run two = render(args, 2);
    EXPECT_EQ(two.result.exit_code, single.result.exit_code) << single.result.output << "\n---\n" << two.result.output;
    EXPECT_EQ(two.warnings, single.warnings) << two.result.output;
    EXPECT_EQ(two.errors.size(), single.errors.size()) << two.result.output;
    return single;
  }
};

std::filesystem::path first_file(const std::filesystem::path& folder) {
  std::vector<std::filesystem::path> files;
  for (const auto& e : std::filesystem::recursive_directory_iterator(folder)) {
    if (e.is_regular_file() && e.path().filename().string()[0] != '.') files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  return files.empty() ? folder : files.front();
}

constexpr const char* kStore = " --cache-mb 16 --brick 8 --block 8 --size 48x48 --frames 40";

TEST_F(DistributedDataFault, ACorruptChunkIsRenderedAsMissingWithTheSameWarning) {
  const auto store = make_store([](const std::filesystem::path& s) { test::write_text(first_file(s / "0"), std::string(300, 'x')); });
  const Run single = expect_like_single_process("--volume " + store.string() + kStore + " --lod 0 --allow-partial");
  EXPECT_EQ(single.result.exit_code, 0) << single.result.output;
  ASSERT_EQ(single.warnings.size(), 1u) << single.result.output;
  EXPECT_NE(single.warnings[0].find("brick failed to load, rendered as missing"), std::string::npos);
}

TEST_F(DistributedDataFault, ATruncatedChunkAtEveryLevelIsRenderedAsMissing) {
  const auto store = make_store([](const std::filesystem::path& s) {
    for (const char* level : {"0", "1", "2"}) {
      if (!std::filesystem::exists(s / level)) continue;
      const auto c = first_file(s / level);
      std::filesystem::resize_file(c, std::filesystem::file_size(c) / 2);
    }
  });
  const Run single = expect_like_single_process("--volume " + store.string() + kStore + " --allow-partial");
  EXPECT_EQ(single.result.exit_code, 0) << single.result.output;
  EXPECT_FALSE(single.warnings.empty()) << single.result.output;
}

// Without --allow-partial the image is incomplete (the failed bricks stay missing): status 4 on every
// rank, the same line as one process.
TEST_F(DistributedDataFault, ACorruptChunkLeavesTheImageIncompleteAsInOneProcess) {
  const auto store = make_store([](const std::filesystem::path& s) { test::write_text(first_file(s / "0"), std::string(300, 'x')); });
  const Run single = expect_like_single_process("--volume " + store.string() + kStore);
  EXPECT_EQ(single.result.exit_code, 4) << single.result.output;
  EXPECT_EQ(single.warnings.size(), 1u) << single.result.output;
}

TEST_F(DistributedDataFault, StrictExitsOneOnEveryRank) {
  const auto store = make_store([](const std::filesystem::path& s) { test::write_text(first_file(s / "0"), std::string(300, 'x')); });
  const Run single = expect_like_single_process("--volume " + store.string() + kStore + " --lod 0 --strict");
  EXPECT_EQ(single.result.exit_code, 1) << single.result.output;
  ASSERT_EQ(single.errors.size(), 1u) << single.result.output;
  EXPECT_NE(single.errors[0].find("bricks failed to load (--strict)"), std::string::npos);
}

// A missing chunk is the fill value, not a fault: the same image status with and without ranks.
TEST_F(DistributedDataFault, AMissingChunkIsTheFillValue) {
  const auto store = make_store([](const std::filesystem::path& s) { std::filesystem::remove(first_file(s / "0")); });
  const Run single = expect_like_single_process("--volume " + store.string() + kStore + " --lod 0 --strict");
  EXPECT_EQ(single.result.exit_code, 0) << single.result.output;
  EXPECT_TRUE(single.warnings.empty()) << single.result.output;
}

}  // namespace
}  // namespace sl
