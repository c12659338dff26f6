// The `sparseleap` executable end to end: the default render, and every bad-input case giving one
// clear line naming the file, a non-zero exit, and no output left looking complete.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>

#include "core/scene/generate.h"
#include "cache/formats/nrrd/nrrd.h"
#include "core/util/image.h"
#include "tests/test_util.h"

namespace sl {
namespace {

namespace fs = std::filesystem;

int count_lines(const std::string& s) {
  int n = 0;
  for (char c : s) n += c == '\n';
  return n;
}

// Runs a command that must fail: exit code non-zero, exactly one line naming `needle`.
void expect_one_line_error(const std::string& args, const std::string& needle) {
  const test::RunResult r = test::run_sparseleap(args);
  EXPECT_NE(r.exit_code, 0) << args;
  EXPECT_EQ(count_lines(r.output), 1) << args << "\n" << r.output;
  EXPECT_NE(r.output.find("sparseleap: "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(needle), std::string::npos) << "expected '" << needle << "' in: " << r.output;
}

TEST(Cli, DefaultRenderShowsTheBuiltInNeurites) {
  const auto dir = test::scratch_dir();
  const std::string out = (dir / "frame").string();
  const test::RunResult r = test::run_sparseleap("render --backend cpu --size 96x80 --out " + out +
                                                 " --stats-json " + (dir / "stats.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("96x80 cpu"), std::string::npos) << r.output;
  const Image exr = read_exr(out + ".exr");
  EXPECT_EQ(exr.width, 96);
  EXPECT_EQ(exr.height, 80);
  ASSERT_TRUE(exr.channels.count("samples"));
  float alpha = 0, samples = 0;
  for (const vec4& c : exr.rgba) alpha += c.w;
  for (float s : exr.channels.at("samples")) samples += s;
  EXPECT_GT(alpha, 5.0f);      // something is visible
  EXPECT_GT(samples, 1000.0f);
  const Image png = read_png(out + ".png");
  EXPECT_EQ(png.width, 96);
  const std::string stats = test::read_text(dir / "stats.json");
  EXPECT_NE(stats.find("\"raycast\""), std::string::npos);
  EXPECT_NE(stats.find("\"samples\""), std::string::npos);
}

TEST(Cli, GenThenRenderFromNrrd) {
  const auto dir = test::scratch_dir();
  const std::string vol = (dir / "blobs.nrrd").string();
  test::RunResult r = test::run_sparseleap("gen blobs --dims 40x33x27 --out " + vol);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(dir / "blobs_labels.nrrd"));
  r = test::run_sparseleap("render --backend cpu --volume " + vol + " --labels " +
                           (dir / "blobs_labels.nrrd").string() + " --mode labels --size 32x32 --out " +
                           (dir / "b").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = test::run_sparseleap("info " + vol);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("40 x 33 x 27"), std::string::npos) << r.output;
}

class CliBadInput : public ::testing::Test {
 protected:
  void SetUp() override {
    dir = test::scratch_dir();
    out = (dir / "out" ).string();
  }
  // After a failed run, nothing that looks like output exists.
  void TearDown() override {
    EXPECT_FALSE(fs::exists(out + ".png"));
    EXPECT_FALSE(fs::exists(out + ".exr"));
  }
  std::string render(const std::string& args) { return "render --size 16x16 --out " + out + " " + args; }
  fs::path dir;
  std::string out;
};

TEST_F(CliBadInput, MissingVolumeFile) {
  expect_one_line_error(render("--volume " + (dir / "nope.nrrd").string()), "nope.nrrd");
}

TEST_F(CliBadInput, TruncatedNrrd) {
  const auto p = dir / "trunc.nrrd";
  test::write_text(p, "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 10 10 10\nencoding: raw\n\n" +
                          std::string(300, 'x'));
  expect_one_line_error(render("--volume " + p.string()), "trunc.nrrd");
}

TEST_F(CliBadInput, HeaderSizesDisagreeWithData) {
  const auto p = dir / "short.nhdr";
  test::write_text(dir / "short.raw", std::string(999, '\1'));
  test::write_text(p, "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 10 10 10\nencoding: raw\ndata file: short.raw\n");
  expect_one_line_error(render("--volume " + p.string()), "short");
}

TEST_F(CliBadInput, UnknownTypeAndEncoding) {
  test::write_text(dir / "t.nrrd", "NRRD0004\ntype: complex\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n");
  expect_one_line_error(render("--volume " + (dir / "t.nrrd").string()), "t.nrrd");
  test::write_text(dir / "e.nrrd", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: bzip2\n\n");
  expect_one_line_error(render("--volume " + (dir / "e.nrrd").string()), "e.nrrd");
}

TEST_F(CliBadInput, AbsurdDims) {
  test::write_text(dir / "huge.nrrd",
                   "NRRD0004\ntype: float\ndimension: 3\nsizes: 4000000 4000000 4000000\nencoding: raw\n\n");
  expect_one_line_error(render("--volume " + (dir / "huge.nrrd").string()), "huge.nrrd");
  test::write_text(dir / "zero.nrrd", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 0 4 4\nencoding: raw\n\n");
  expect_one_line_error(render("--volume " + (dir / "zero.nrrd").string()), "zero.nrrd");
}

TEST_F(CliBadInput, NotANrrd) {
  test::write_text(dir / "junk.nrrd", "hello world\n");
  expect_one_line_error(render("--volume " + (dir / "junk.nrrd").string()), "junk.nrrd");
}

TEST_F(CliBadInput, MalformedTransferFunctionJson) {
  test::write_text(dir / "tf.json", "{\"points\": [ {\"value\": 1, ");
  expect_one_line_error(render("--tf " + (dir / "tf.json").string()), "tf.json");
}

TEST_F(CliBadInput, MalformedCameraJson) {
  test::write_text(dir / "cam.json", "{\"eye\": [1, 2], \"center\": [0, 0, 0]}");
  expect_one_line_error(render("--camera " + (dir / "cam.json").string()), "cam.json");
}

TEST_F(CliBadInput, UnwritableOutput) {
  out = (dir / "no-such-dir" / "frame").string();
  expect_one_line_error("render --size 16x16 --out " + out, "no-such-dir");
}

TEST_F(CliBadInput, BadOptions) {
  expect_one_line_error(render("--size 0x10"), "--size");
  expect_one_line_error(render("--size big"), "--size");
  expect_one_line_error(render("--mode xray"), "--mode");
  expect_one_line_error(render("--backend opencl"), "--backend");
  expect_one_line_error(render("--step -1"), "--step");
}

TEST_F(CliBadInput, LabelDimsMismatch) {
  GeneratedVolume g = generate_volume("blobs", ivec3(12, 10, 8), 1);
  write_nrrd((dir / "v.nrrd").string(), g.intensity);
  GeneratedVolume h = generate_volume("blobs", ivec3(12, 10, 9), 1);
  write_nrrd((dir / "l.nrrd").string(), h.labels);
  expect_one_line_error(render("--volume " + (dir / "v.nrrd").string() + " --labels " + (dir / "l.nrrd").string()),
                        "l.nrrd");
}

}  // namespace
}  // namespace sl

namespace sl {
namespace {

TEST(CliBench, WritesCsvAndJsonForEveryMethod) {
  const auto dir = test::scratch_dir();
  const std::string csv = (dir / "b.csv").string(), json = (dir / "b.json").string();
  const test::RunResult r = test::run_sparseleap(
      "bench --volume builtin:neurites:48x40x36 --orbit 3 --size 32x24 --warmup 0 --enable fraction:0.5:1 --csv " +
      csv + " --json " + json);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  for (const char* m : {"none", "bbox", "octree", "sparseleap"}) {
    EXPECT_NE(r.output.find(m), std::string::npos) << r.output;
  }
  const std::string j = test::read_text(json);
  for (const char* key : {"\"median_ms\"", "\"p95_ms\"", "\"samples\"", "\"useful_samples\"", "\"depth_complexity_avg\"",
                          "\"sparseleap\""}) {
    EXPECT_NE(j.find(key), std::string::npos) << key;
  }
  const std::string c = test::read_text(csv);
  int rows = 0;
  for (char ch : c) rows += ch == '\n';
  EXPECT_EQ(rows, 1 + 4 * 3 * 2);  // header + method x frame x (with, without rasterization)
}

TEST(CliBench, BadInput) {
  const auto dir = test::scratch_dir();
  test::write_text(dir / "path.json", "{\"keyframes\": 7}");
  auto r = test::run_sparseleap("bench --path " + (dir / "path.json").string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("path.json"), std::string::npos) << r.output;
  r = test::run_sparseleap("bench --methods none,warp --volume builtin:neurites:16x16x16");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("--method"), std::string::npos) << r.output;
  r = test::run_sparseleap("bench --volume builtin:neurites:0x16x16");
  EXPECT_NE(r.exit_code, 0);
  r = test::run_sparseleap("bench --volume builtin:nope");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("nope"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace sl

namespace sl {
namespace {

TEST(CliOutOfCore, RenderConvergesAndReportsCacheStats) {
  const auto dir = test::scratch_dir();
  const test::RunResult r = test::run_sparseleap(
      "render --volume builtin:neurites:64x64x64 --cache-mb 8 --brick 16 --frames 12 --size 48x40 --out " +
      (dir / "o").string() + " --stats-json " + (dir / "o.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("out of core"), std::string::npos) << r.output;
  const std::string j = test::read_text(dir / "o.json");
  for (const char* key : {"\"cache\"", "\"resident_mb\"", "\"loads\"", "\"evictions\"", "\"page_table_bytes\"", "\"tree_bytes\"",
                          "\"converged_at_frame\"", "\"metadata_blocks\""}) {
    EXPECT_NE(j.find(key), std::string::npos) << key;
  }
  EXPECT_EQ(j.find("\"converged_at_frame\": -1"), std::string::npos) << "12 frames suffice to converge: " << j;
}

TEST(CliOutOfCore, BadOptions) {
  const auto dir = test::scratch_dir();
  const std::string out = " --out " + (dir / "o").string();
  // Three 66³ bricks with their u32 labels (shown: --enable) do not fit 1 MB.
  auto r = test::run_sparseleap("render --volume builtin:neurites:256x256x256 --enable all --cache-mb 1 --brick 64 --size 8x8" + out);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("--cache-mb"), std::string::npos) << r.output;
  r = test::run_sparseleap("render --volume procedural:neurites:0x10x10 --size 8x8" + out);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("procedural"), std::string::npos) << r.output;
  r = test::run_sparseleap("render --volume builtin:neurites:32x32x32 --cache-mb 8 --lod 9 --size 8x8" + out);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("--lod"), std::string::npos) << r.output;
  r = test::run_sparseleap("render --volume builtin:neurites:32x32x32 --cache-mb 8 --method octree --size 8x8" + out);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_FALSE(std::filesystem::exists(dir / "o.png"));
}

TEST(CliOutOfCore, BenchReportsFramesToConvergencePerView) {
  const auto dir = test::scratch_dir();
  const test::RunResult r = test::run_sparseleap(
      "bench --volume builtin:neurites:48x48x48 --cache-mb 8 --brick 16 --orbit 2 --size 32x32 --json " +
      (dir / "b.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string j = test::read_text(dir / "b.json");
  EXPECT_NE(j.find("\"frames_to_converge\""), std::string::npos) << j;
  EXPECT_NE(j.find("\"loads_per_frame\""), std::string::npos) << j;
}

// Issue 14's soak flags: a generated orbit-zoom path, RSS at given frames, stalls, time to
// convergence and metadata memory in the JSON; prefetch counted apart; bad values are one line.
// bench's frames do not wait for the loader, and a 32x32 frame takes about a millisecond: on a loaded
// machine a view's default 40 frames can pass before a starved loader delivers. A view has 2000 frames
// here; it converges in about ten.
TEST(CliOutOfCore, BenchSoakFlagsReportRssStallsAndConvergence) {
  const auto dir = test::scratch_dir();
  test::RunResult r = test::run_sparseleap(
      "bench --volume builtin:neurites:48x48x48 --cache-mb 8 --brick 16 --path-kind orbit-zoom --orbit 6 "
      "--size 32x32 --prefetch on --rss-at 1,3,100000 --max-frames-per-view 2000 --max-frames 20000 --json " +
      (dir / "b.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("RSS at frame 1: "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("RSS at frame 3: "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("RSS at frame 100000: not reached"), std::string::npos) << r.output;
  const nlohmann::json j = nlohmann::json::parse(test::read_text(dir / "b.json"));
  const nlohmann::json& m = j["methods"]["sparseleap"];
  EXPECT_EQ(m["views_rendered"], 6);
  EXPECT_EQ(m["unconverged_views"], 0);
  EXPECT_GT(m["rss_mb_at_frame"]["1"].get<double>(), 1.0);
  EXPECT_FALSE(m["rss_mb_at_frame"].contains("100000"));
  EXPECT_GT(m["page_table_bytes"].get<double>(), 0.0);
  EXPECT_GT(m["tree_bytes"].get<double>(), 0.0);
  EXPECT_TRUE(m.contains("stall_frames"));
  EXPECT_TRUE(m.contains("prefetch_hits"));
  EXPECT_TRUE(j["prefetch"].get<bool>());
  int frames = 0;
  for (const auto& v : m["views"]) {
    EXPECT_GT(v["frames_to_converge"].get<int>(), 0);
    EXPECT_GT(v["ms_to_converge"].get<double>(), 0.0);
    frames += v["frames_to_converge"].get<int>();
  }
  EXPECT_EQ(m["frames"].get<int>(), frames);

  // --max-frames stops the run; the view it cuts is not counted as unconverged.
  r = test::run_sparseleap("bench --volume builtin:neurites:48x48x48 --cache-mb 8 --brick 16 --path-kind zoom-in "
                           "--orbit 6 --size 32x32 --max-frames 2 --json " + (dir / "c.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const nlohmann::json c = nlohmann::json::parse(test::read_text(dir / "c.json"));
  EXPECT_EQ(c["methods"]["sparseleap"]["frames"], 2);
  EXPECT_EQ(c["methods"]["sparseleap"]["unconverged_views"], 0);

  for (const char* bad : {"--path-kind spiral", "--rss-at 0", "--rss-at 10,x", "--prefetch maybe", "--max-frames -1"}) {
    r = test::run_sparseleap(std::string("bench --volume builtin:neurites:16x16x16 --cache-mb 8 --brick 16 --size 8x8 ") + bad);
    EXPECT_NE(r.exit_code, 0) << bad;
    const std::string flag = std::string(bad).substr(0, std::string(bad).find(' '));
    EXPECT_NE(r.output.find(flag), std::string::npos) << bad << ": " << r.output;
  }
  test::write_text(dir / "p.json", "{\"keyframes\":[{\"eye\":[0,0,50],\"center\":[8,8,8],\"up\":[0,1,0]}]}");
  r = test::run_sparseleap("bench --volume builtin:neurites:16x16x16 --cache-mb 8 --brick 16 --size 8x8 --path-kind orbit --path " +
                           (dir / "p.json").string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("--path-kind"), std::string::npos) << r.output;
  r = test::run_sparseleap("bench --volume builtin:neurites:16x16x16 --size 8x8 --rss-at 5");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("--rss-at"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace sl

namespace sl {
namespace {

// A real NIfTI-1 file written by another tool: the Colin27 T1 template of Debian's mricron-data
// (what scripts/bench-peers renders). info reads its header, render reads it whole, and the voxels are
// those `ingest` streams into a store.
TEST(Cli, NiftiFromMricronRendersAndReportsItsHeader) {
  const std::string nii = "/usr/share/mricron/templates/ch2.nii.gz";
  if (!std::filesystem::exists(nii)) {
    SL_SKIP_OR_FAIL("mricron-data is not installed (" + nii + ")");
  }
  test::RunResult r = test::run_sparseleap("info " + nii);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("dims    181 x 217 x 181"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("type    u8"), std::string::npos) << r.output;
  const auto dir = test::scratch_dir();
  const std::string out = (dir / "mri").string();
  r = test::run_sparseleap("render --backend cpu --size 48x40 --volume " + nii + " --out " + out);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  float alpha = 0.0f;
  for (const vec4& c : read_exr(out + ".exr").rgba) alpha += c.w;
  EXPECT_GT(alpha, 50.0f) << "the head fills much of the frame";
  // A truncated .nii.gz is one line naming the file.
  const std::string cut = (dir / "cut.nii.gz").string();
  {
    std::ifstream in(nii, std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::ofstream(cut, std::ios::binary) << bytes.substr(0, bytes.size() / 3);
  }
  expect_one_line_error("render --backend cpu --size 16x16 --volume " + cut + " --out " + (dir / "x").string(),
                        "cut.nii.gz");
  EXPECT_FALSE(std::filesystem::exists(dir / "x.png"));
}

}  // namespace
}  // namespace sl

namespace sl {
namespace {

// --fine-cell changes how many samples SparseLeap takes, never the image (core/occupancy/fine_occupancy.h).
TEST(Cli, FineCellsKeepTheImageAndSkipSamples) {
  const auto dir = test::scratch_dir();
  std::vector<Image> frames;
  std::vector<double> samples;
  for (const std::string cell : {"0", "4", "8", "auto"}) {
    const std::string out = (dir / ("f" + cell)).string();
    const test::RunResult r = test::run_sparseleap("render --backend cpu --size 64x48 --enable fraction:0.3:2 "
                                                   "--fine-cell " + cell + " --out " + out);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    frames.push_back(read_exr(out + ".exr"));
    double n = 0;
    for (float s : frames.back().channels.at("samples")) n += s;
    samples.push_back(n);
  }
  for (std::size_t k = 1; k < frames.size(); ++k) {
    EXPECT_EQ(std::memcmp(frames[k].rgba.data(), frames[0].rgba.data(), frames[0].rgba.size() * sizeof(vec4)), 0);
    EXPECT_LT(samples[k], samples[0]);
  }
  // auto (the default) is 8³ cells where the voxel mask applies, as here (u8, dvr, trilinear).
  EXPECT_EQ(samples[3], samples[2]);
  expect_one_line_error("render --fine-cell 6 --out " + (dir / "bad").string(), "--fine-cell");
  expect_one_line_error("render --fine-cell -1 --out " + (dir / "bad").string(), "--fine-cell");
}

// --voxel-mask (on by default) fetches fewer samples inside the fine cells, never changes the image.
TEST(Cli, VoxelMaskKeepsTheImageAndFetchesFewerSamples) {
  const auto dir = test::scratch_dir();
  std::vector<Image> frames;
  std::vector<double> samples;
  for (const char* mode : {"dvr", "labels"}) {
    for (const char* on : {"off", "on"}) {
      const std::string out = (dir / (std::string(mode) + on)).string();
      const test::RunResult r = test::run_sparseleap("render --backend cpu --size 64x48 --enable fraction:0.3:2 --mode " +
                                                     std::string(mode) + " --voxel-mask " + on + " --out " + out);
      ASSERT_EQ(r.exit_code, 0) << r.output;
      frames.push_back(read_exr(out + ".exr"));
      double n = 0;
      for (float s : frames.back().channels.at("samples")) n += s;
      samples.push_back(n);
    }
  }
  for (std::size_t k = 0; k < frames.size(); k += 2) {
    EXPECT_EQ(std::memcmp(frames[k].rgba.data(), frames[k + 1].rgba.data(), frames[k].rgba.size() * sizeof(vec4)), 0);
    EXPECT_EQ(frames[k].channels.at("depth"), frames[k + 1].channels.at("depth"));
    EXPECT_LT(samples[k + 1], samples[k]);
  }
  expect_one_line_error("render --voxel-mask yes --out " + (dir / "bad").string(), "--voxel-mask");
}

// The frames of `render --FLAG off` and `--FLAG on` (64x48, --ert, CPU) in `mode`, after checking that
// both agree bit for bit on what the frame records: colour, depth and the per-pixel sample counts.
std::vector<Image> frames_off_and_on(const fs::path& dir, const std::string& flag, const char* mode) {
  std::vector<Image> frames;
  for (const char* on : {"off", "on"}) {
    const std::string out = (dir / (flag + mode + on)).string();
    const test::RunResult r = test::run_sparseleap("render --backend cpu --size 64x48 --ert --mode " +
                                                   std::string(mode) + " --" + flag + " " + on + " --out " + out);
    EXPECT_EQ(r.exit_code, 0) << r.output;
    frames.push_back(read_exr(out + ".exr"));
  }
  EXPECT_EQ(std::memcmp(frames[0].rgba.data(), frames[1].rgba.data(), frames[0].rgba.size() * sizeof(vec4)), 0)
      << flag << ' ' << mode;
  EXPECT_EQ(frames[0].channels.at("depth"), frames[1].channels.at("depth")) << flag << ' ' << mode;
  EXPECT_EQ(frames[0].channels.at("samples"), frames[1].channels.at("samples")) << flag << ' ' << mode;
  return frames;
}

// --simd (on by default: eight samples at a time where the CPU has AVX2) changes nothing the frame
// records: colour, depth and the per-pixel sample counts are those of the scalar caster, bit for bit.
TEST(Cli, SimdKeepsTheImageDepthAndSampleCounts) {
  const auto dir = test::scratch_dir();
  for (const char* mode : {"dvr", "labels"}) frames_off_and_on(dir, "simd", mode);
  expect_one_line_error("render --simd 1 --out " + (dir / "bad").string(), "--simd");
}

// --tight-boxes (on by default) changes the lists, not what the frame records: colour, depth and the
// per-pixel sample counts are those of the unshrunk boxes, bit for bit; fewer segments per ray.
TEST(Cli, TightBoxesKeepTheImageDepthAndSampleCounts) {
  const auto dir = test::scratch_dir();
  for (const char* mode : {"dvr", "labels"}) {
    const std::vector<Image> frames = frames_off_and_on(dir, "tight-boxes", mode);
    float dc_off = 0.0f, dc_on = 0.0f;
    for (float v : frames[0].channels.at("depth_complexity")) dc_off += v;
    for (float v : frames[1].channels.at("depth_complexity")) dc_on += v;
    EXPECT_NE(dc_off, dc_on) << mode << ": the shrunk boxes should change the lists";
  }
  expect_one_line_error("render --tight-boxes 1 --out " + (dir / "bad").string(), "--tight-boxes");
}

}  // namespace
}  // namespace sl

namespace sl {
namespace {

// Issue 15: inputs that crashed, hung, destroyed data or gave the wrong error.
TEST(CliRobust, NonFiniteVoxelsRenderInAndOutOfCore) {
  const auto dir = test::scratch_dir();
  Volume v(VolumeDesc{{24, 24, 24}, vec3(1.0f), VoxelType::F32});
  for (int z = 0; z < 24; ++z)
    for (int y = 0; y < 24; ++y)
      for (int x = 0; x < 24; ++x) v.set(x, y, z, float(x + y + z));
  float* f = v.as<float>();
  f[0] = std::numeric_limits<float>::quiet_NaN();  // first voxel: block min/max start from NaN
  f[5000] = std::numeric_limits<float>::quiet_NaN();
  f[7000] = std::numeric_limits<float>::infinity();
  f[9000] = -std::numeric_limits<float>::infinity();
  const std::string vol = (dir / "nan.nrrd").string();
  write_nrrd(vol, v);
  const fs::path tf = dir / "tf.json";
  test::write_text(tf, "{\"points\":[{\"value\":0,\"rgba\":[0,0,0,0]},{\"value\":70,\"rgba\":[1,1,1,1]}]}");
  // The default transfer function spans the finite values; an explicit one segfaulted on NaN.
  for (const std::string& tf_arg : {std::string(), " --tf " + tf.string()}) {
    for (const std::string mode : {"dvr", "mip", "iso"}) {
      for (const std::string ooc : {"", " --cache-mb 64"}) {
        const std::string args = "render --backend cpu --size 32x32 --volume " + vol + tf_arg + " --mode " + mode +
                                 ooc + " --out " + (dir / ("f_" + mode)).string();
        const test::RunResult r = test::run_sparseleap(args);
        EXPECT_EQ(r.exit_code, 0) << args << "\n" << r.output;
      }
    }
  }
}

TEST(CliRobust, NanFillValueOfAMissingZarrChunkRenders) {
  const auto dir = test::scratch_dir();
  Volume v(VolumeDesc{{16, 16, 16}, vec3(1.0f), VoxelType::F32});
  for (int z = 0; z < 16; ++z)
    for (int y = 0; y < 16; ++y)
      for (int x = 0; x < 16; ++x) v.set(x, y, z, float(x + y + z));
  const std::string vol = (dir / "f.nrrd").string(), store = (dir / "f.zarr").string();
  write_nrrd(vol, v);
  ASSERT_EQ(test::run_sparseleap("ingest " + vol + " " + store + " --chunk 8").exit_code, 0);
  const fs::path zarray = fs::path(store) / "0" / ".zarray";
  std::string meta = test::read_text(zarray);
  const auto pos = meta.find("\"fill_value\": 0.0");
  ASSERT_NE(pos, std::string::npos) << meta;
  meta.replace(pos, std::strlen("\"fill_value\": 0.0"), "\"fill_value\": \"NaN\"");
  test::write_text(zarray, meta);
  ASSERT_TRUE(fs::remove(fs::path(store) / "0" / "1" / "1" / "1"));
  const fs::path tf = dir / "tf.json";
  test::write_text(tf, "{\"points\":[{\"value\":0,\"rgba\":[0,0,0,0]},{\"value\":45,\"rgba\":[1,1,1,1]}]}");
  for (const std::string mode : {"dvr", "mip", "iso"}) {
    for (const std::string ooc : {"", " --cache-mb 64"}) {
      const std::string args = "render --backend cpu --size 32x32 --volume " + store + " --tf " + tf.string() +
                               " --mode " + mode + ooc + " --out " + (dir / ("z_" + mode)).string();
      const test::RunResult r = test::run_sparseleap(args);
      EXPECT_EQ(r.exit_code, 0) << args << "\n" << r.output;
    }
  }
}

TEST(CliRobust, RefusedInputsGiveOneLine) {
  const auto dir = test::scratch_dir();
  const std::string out = " --size 8x8 --out " + (dir / "x").string();
  expect_one_line_error("render --step 1e-9" + out, "--step: step must be in [0.001, 64]");
  expect_one_line_error("render --cache-mb -1" + out, "--cache-mb: must be positive");
  expect_one_line_error("render --threads -1" + out, "--threads");
  expect_one_line_error("render --iso nan" + out, "--iso: must be a finite number");
  expect_one_line_error("render --tf " + dir.string() + out, dir.string() + ": is a directory");
  const fs::path cam = dir / "cam.json";
  test::write_text(cam, "{\"eye\":[1e999,0,0],\"center\":[0,0,0]}");
  expect_one_line_error("render --camera " + cam.string() + out, cam.string() + ": malformed JSON");
  const test::RunResult r = test::run_sparseleap("render --cache-mb -1" + out);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_FALSE(fs::exists(dir / "x.png"));
}

TEST(CliRobust, NanOrNegativeNrrdSpacingIsRefused) {
  const auto dir = test::scratch_dir();
  for (const char* sp : {"nan 1 1", "1 -2 1"}) {
    const fs::path p = dir / "sp.nrrd";
    test::write_text(p, std::string("NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nspacings: ") + sp +
                            "\nencoding: raw\n\n" + std::string(8, '\x10'));
    expect_one_line_error("render --volume " + p.string() + " --size 8x8 --out " + (dir / "x").string(),
                          "sp.nrrd: spacing");
  }
}

TEST(CliRobust, HugeLabelIdIsRefusedNamingTheFile) {
  const auto dir = test::scratch_dir();
  Volume vol(VolumeDesc{{8, 8, 8}, vec3(1.0f), VoxelType::U8});
  Volume lab(VolumeDesc{{8, 8, 8}, vec3(1.0f), VoxelType::U32});
  lab.as<std::uint32_t>()[3] = 0xFFFFFFFFu;
  const std::string vp = (dir / "v.nrrd").string(), lp = (dir / "l.nrrd").string();
  write_nrrd(vp, vol);
  write_nrrd(lp, lab);
  expect_one_line_error("render --volume " + vp + " --labels " + lp + " --mode labels --size 8x8 --out " +
                            (dir / "x").string(),
                        "l.nrrd: largest label id 4294967295 would need a 512 MiB label table");
}

TEST(CliRobust, IngestRefusesToOverwriteItsInput) {
  const auto dir = test::scratch_dir();
  const std::string in = (dir / "in.nrrd").string();
  write_nrrd(in, Volume(VolumeDesc{{8, 8, 8}, vec3(1.0f), VoxelType::U8}));
  const auto before = fs::file_size(in);
  expect_one_line_error("ingest " + in + " " + in + " --force", "is the input");
  expect_one_line_error("ingest " + in + " " + dir.string() + " --force", "is the input");
  EXPECT_TRUE(fs::is_regular_file(in));
  EXPECT_EQ(fs::file_size(in), before);
}

}  // namespace
}  // namespace sl
