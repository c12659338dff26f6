// `sparseleap render` out of core renders the one view until the image is complete: without --frames
// it stops when the renderer has converged with every sample at its level, writes that image and exits
// 0; stopped short by --max-frames or --time-budget it writes the last frame, says how complete it is
// in one line and exits 4, or 0 with --allow-partial.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <system_error>

#include <unistd.h>

#include <nlohmann/json.hpp>

#include "cache/formats/nrrd/nrrd.h"
#include "core/scene/generate.h"
#include "core/util/image.h"
#include "tests/test_util.h"

namespace sl {
namespace {

namespace fs = std::filesystem;

constexpr int kPartial = 4;  // docs/cli.md "Errors, exit status and outputs"

int lines(const std::string& s) {
  int n = 0;
  for (char c : s) n += c == '\n';
  return n;
}

bool has(const std::string& text, const std::string& what) { return text.find(what) != std::string::npos; }

// A 128³ neurites store in 16³ chunks (2 MiB of u8 at level 0): a 1 MB cache of 8³ bricks holds less than the
// volume but the view's non-empty bricks.
class RenderComplete : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    // ctest runs each test in its own process, possibly at once: the suite's folder is the process's own.
    dir_ = new fs::path(fs::path(SL_BINARY_DIR) / "test-scratch" / ("RenderComplete." + std::to_string(getpid())));
    fs::remove_all(*dir_);
    fs::create_directories(*dir_);
    GeneratedVolume g = generate_volume("neurites", ivec3(128), 5);
    write_nrrd((*dir_ / "n.nrrd").string(), g.intensity);
    const test::RunResult r =
        test::run_sparseleap("ingest " + (*dir_ / "n.nrrd").string() + " " + store() + " --chunk 16");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const test::RunResult in_core = render("in_core", "");
    ASSERT_EQ(in_core.exit_code, 0) << in_core.output;
  }
  static void TearDownTestSuite() {
    std::error_code ec;
    fs::remove_all(*dir_, ec);
    delete dir_;
    dir_ = nullptr;
  }
  static std::string store() { return (*dir_ / "n.zarr").string(); }
  static std::string out(const std::string& name) { return (*dir_ / name).string(); }
  static test::RunResult render(const std::string& name, const std::string& args) {
    return test::run_sparseleap("render --backend cpu --size 64x48 --volume " + store() + " --out " + out(name) +
                                " " + args + " 2>&1");
  }
  static fs::path* dir_;
};
fs::path* RenderComplete::dir_ = nullptr;

TEST_F(RenderComplete, WithoutFramesTheImageIsCompleteAndEqualsInCore) {
  const test::RunResult r = render("ooc", "--cache-mb 1 --brick 8 --block 8 --lod 0 --stats-json " + out("ooc.json"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(has(r.output, "out of core, ")) << r.output;
  EXPECT_FALSE(has(r.output, "incomplete")) << r.output;
  EXPECT_FALSE(has(r.output, "\r")) << "no progress line when stderr is not a terminal: " << r.output;
  EXPECT_EQ(lines(r.output), 1) << r.output;  // the summary alone
  const std::string stats = test::read_text(out("ooc.json"));
  EXPECT_FALSE(has(stats, "\"converged_at_frame\": -1")) << stats;
  EXPECT_TRUE(has(stats, "\"completeness\": 1.0")) << stats;
  const Image a = read_exr(out("ooc") + ".exr"), b = read_exr(out("in_core") + ".exr");
  EXPECT_EQ(a.rgba, b.rgba);
  float alpha = 0;
  for (const vec4& p : a.rgba) alpha += p.w;
  EXPECT_GT(alpha, 1.0f) << "the neurites are visible";
}

TEST_F(RenderComplete, StoppedByMaxFramesIsPartialUnlessAllowed) {
  test::RunResult r = render("one", "--cache-mb 1 --brick 8 --block 8 --lod 0 --max-frames 1");
  EXPECT_EQ(r.exit_code, kPartial) << r.output;
  EXPECT_TRUE(fs::exists(out("one") + ".png"));
  EXPECT_TRUE(fs::exists(out("one") + ".exr"));
  EXPECT_TRUE(has(r.output, "sparseleap: incomplete image written to " + out("one") + ".png and " + out("one") +
                                ".exr: ")) << r.output;
  EXPECT_TRUE(has(r.output, "after 1 frames in ")) << r.output;
  EXPECT_TRUE(has(r.output, "(--max-frames); a larger --max-frames or --cache-mb, or --allow-partial")) << r.output;
  EXPECT_EQ(lines(r.output), 2) << "the summary and the one line: " << r.output;

  r = render("one_ok", "--cache-mb 1 --brick 8 --block 8 --lod 0 --max-frames 1 --allow-partial");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(has(r.output, "sparseleap: partial (--allow-partial) image written to ")) << r.output;
  EXPECT_TRUE(fs::exists(out("one_ok") + ".exr"));

  r = render("budget", "--cache-mb 1 --brick 8 --block 8 --lod 0 --time-budget 0.000001");
  EXPECT_EQ(r.exit_code, kPartial) << r.output;
  EXPECT_TRUE(has(r.output, "after 1 frames in ")) << r.output;
  EXPECT_TRUE(has(r.output, "(--time-budget 1e-06); a larger --time-budget")) << r.output;
}

// --frames N renders exactly N frames; the exit status follows the same complete/partial rule.
TEST_F(RenderComplete, ExactFramesFollowTheSameRule) {
  test::RunResult r = render("f1", "--cache-mb 1 --brick 8 --block 8 --lod 0 --frames 1");
  EXPECT_EQ(r.exit_code, kPartial) << r.output;
  EXPECT_TRUE(has(r.output, "after 1 frames in ")) << r.output;
  EXPECT_TRUE(has(r.output, "(--frames); more --frames")) << r.output;
  r = render("f200", "--cache-mb 1 --brick 8 --block 8 --lod 0 --frames 200");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(has(r.output, "out of core, 200 frames in ")) << r.output;
  EXPECT_EQ(read_exr(out("f200") + ".exr").rgba, read_exr(out("in_core") + ".exr").rgba);
}

TEST_F(RenderComplete, FrameCapsRejectBadValuesInOneLine) {
  const auto one_line = [](const test::RunResult& r, int code, const std::string& needle) {
    EXPECT_EQ(r.exit_code, code) << r.output;
    EXPECT_EQ(lines(r.output), 1) << r.output;
    EXPECT_TRUE(has(r.output, needle)) << needle << " in " << r.output;
  };
  for (const char* bad : {"0", "-1", "nan", "inf"}) {
    SCOPED_TRACE(bad);
    one_line(render("bad", std::string("--cache-mb 1 --time-budget ") + bad),
             1, "sparseleap: error: --time-budget: must be a number of seconds greater than 0");
  }
  one_line(render("bad", "--cache-mb 1 --time-budget soon"), 2, "--time-budget");
  one_line(render("bad", "--cache-mb 1 --max-frames 0"), 1, "sparseleap: error: --max-frames: must be between 1");
  one_line(render("bad", "--cache-mb 1 --frames 0"), 1, "sparseleap: error: --frames: must be between 1");
  one_line(render("bad", "--cache-mb 1 --frames 3 --max-frames 5"), 1,
           "sparseleap: error: --max-frames: caps rendering until complete; --frames renders exactly N frames instead");
  one_line(render("bad", "--cache-mb 1 --frames 3 --time-budget 5"), 1, "sparseleap: error: --time-budget: caps");
  EXPECT_FALSE(fs::exists(out("bad") + ".png"));
}

// A procedural volume always renders out of core: without --frames it is complete.
TEST(RenderCompleteProcedural, SmallProceduralVolumeRendersComplete) {
  const fs::path dir = test::scratch_dir();
  const test::RunResult r = test::run_sparseleap(
      "render --backend cpu --volume procedural:neurites:256x256x256 --size 64x64 --out " + (dir / "p").string() +
      " --stats-json " + (dir / "p.json").string() + " 2>&1");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_FALSE(has(r.output, "incomplete")) << r.output;
  const std::string stats = test::read_text(dir / "p.json");
  EXPECT_FALSE(has(stats, "\"converged_at_frame\": -1")) << stats;
  EXPECT_TRUE(has(stats, "\"completeness\": 1.0")) << stats;
}

// The brick cache holds labels only when the render can show them (labels mode, --enable): a DVR
// frame of a labelled volume, or of a procedural one (whose hashed ids nothing shows), has slots of
// intensity and mask alone.
TEST(RenderCacheSlots, LabelsAreCachedOnlyWhenShown) {
  const fs::path dir = test::scratch_dir();
  const auto slot_bytes = [&](const std::string& name, const std::string& args) {
    const std::string json = (dir / (name + ".json")).string();
    const test::RunResult r = test::run_sparseleap("render --backend cpu --size 32x32 --cache-mb 8 " + args + " --out " +
                                                   (dir / name).string() + " --stats-json " + json + " 2>&1");
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return nlohmann::json::parse(test::read_text(json))["cache"]["slot_bytes"].get<std::uint64_t>();
  };
  const std::string labelled = "--volume builtin:organs:48x48x48";
  const std::uint64_t dvr = slot_bytes("dvr", labelled);
  const std::uint64_t masked = slot_bytes("masked", labelled + " --enable 2-3");
  const std::uint64_t shown = slot_bytes("labels", labelled + " --mode labels --enable all");
  const std::uint64_t labels = 34 * 34 * 34 * 2;  // u16 labels of the default 32³ brick and its apron
  EXPECT_EQ(masked - dvr, (labels + 63) / 64 * 64) << "a slot's arrays take whole 64-byte lines";
  EXPECT_EQ(shown, masked);
  EXPECT_EQ(slot_bytes("procedural", "--volume procedural:neurites:256x256x256"), dvr);
}

}  // namespace
}  // namespace sl
