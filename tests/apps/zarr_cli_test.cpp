// OME-Zarr end to end through the `sparseleap` executable: ingest (progress, flags, failures), info on
// a store, and render/bench reading a store in core and out of core, including a corrupt chunk met
// during rendering.
#include <gtest/gtest.h>

#include <filesystem>

#include "core/scene/generate.h"
#include "cache/formats/nrrd/nrrd.h"
#include "core/util/image.h"
#include "tests/test_util.h"

namespace sl {
namespace {

namespace fs = std::filesystem;

int lines(const std::string& s) {
  int n = 0;
  for (char c : s) n += c == '\n';
  return n;
}

class ZarrCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir = test::scratch_dir();
    GeneratedVolume g = generate_volume("neurites", ivec3(72, 64, 80), 3);
    write_nrrd((dir / "n.nrrd").string(), g.intensity);
    write_nrrd((dir / "n_labels.nrrd").string(), g.labels);
  }
  std::string p(const char* name) const { return (dir / name).string(); }
  fs::path dir;
};

TEST_F(ZarrCli, IngestInfoAndRenderMatchTheNrrd) {
  auto r = test::run_sparseleap("ingest " + p("n.nrrd") + " " + p("n.zarr") + " --chunk 16 --labels " + p("n_labels.nrrd"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("wrote " + p("n.zarr")), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("MB/s"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find('\r'), std::string::npos) << "no bar redraws when not a terminal";

  r = test::run_sparseleap("info " + p("n.zarr"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  for (const char* s : {"72 x 64 x 80", "u8", "OME-Zarr", "blosc (zstd", "levels  4", "chunks 16x16x16", "on disk",
                        "labels/labels: u16"}) {
    EXPECT_NE(r.output.find(s), std::string::npos) << s << " in " << r.output;
  }

  // In core: the store's level 0 is the NRRD's volume, so the frames are identical.
  r = test::run_sparseleap("render --backend cpu --size 48x40 --volume " + p("n.zarr") + " --out " + p("z"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = test::run_sparseleap("render --backend cpu --size 48x40 --volume " + p("n.nrrd") + " --out " + p("n"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(read_exr(p("z") + ".exr").rgba, read_exr(p("n") + ".exr").rgba);

  // Out of core: bricks stream from the store's chunks; converged, it equals the NRRD streamed from
  // memory with the same pyramid (the store's pyramids are MemoryVolumeSource's).
  const std::string ooc = " --backend cpu --size 48x40 --cache-mb 16 --brick 16 --frames 20";
  r = test::run_sparseleap("render" + ooc + " --volume " + p("n.zarr") + " --out " + p("zo") + " --stats-json " + p("zo.json"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("out of core"), std::string::npos) << r.output;
  EXPECT_EQ(test::read_text(dir / "zo.json").find("\"converged_at_frame\": -1"), std::string::npos);
  r = test::run_sparseleap("render" + ooc + " --volume " + p("n.nrrd") + " --pyramid max --out " + p("no"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  // The store's max levels are what it shows by default (docs/out-of-core.md "Mean or max pyramid").
  EXPECT_EQ(read_exr(p("zo") + ".exr").rgba, read_exr(p("no") + ".exr").rgba);
  for (const char* what : {"zm", "nm"}) {
    const std::string in = what[0] == 'z' ? p("n.zarr") : p("n.nrrd");
    r = test::run_sparseleap("render" + ooc + " --volume " + in + " --pyramid mean --out " + p(what));
    ASSERT_EQ(r.exit_code, 0) << r.output;
  }
  EXPECT_EQ(read_exr(p("zm") + ".exr").rgba, read_exr(p("nm") + ".exr").rgba);
  EXPECT_NE(read_exr(p("zm") + ".exr").rgba, read_exr(p("zo") + ".exr").rgba) << "the 48x40 view uses coarse levels";

  // Labels from the store's labels/ group (out of core needs --enable for labels mode).
  r = test::run_sparseleap("render" + ooc + " --mode labels --enable all --volume " + p("n.zarr") + " --out " + p("zl"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = test::run_sparseleap("render --backend cpu --size 48x40 --mode labels --enable 1-5 --volume " + p("n.zarr") +
                           " --out " + p("zi"));
  ASSERT_EQ(r.exit_code, 0) << r.output;

  r = test::run_sparseleap("bench --volume " + p("n.zarr") + " --cache-mb 16 --brick 16 --orbit 2 --size 32x32 --json " +
                           p("b.json"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
}

TEST_F(ZarrCli, LabelsFromASeparateStore) {
  auto r = test::run_sparseleap("ingest " + p("n.nrrd") + " " + p("i.zarr") + " --compressor zstd --level 5");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = test::run_sparseleap("ingest " + p("n_labels.nrrd") + " " + p("l.zarr") + " --compressor blosc-lz4");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = test::run_sparseleap("render --backend cpu --size 32x32 --cache-mb 16 --frames 10 --mode labels --enable all --volume " +
                           p("i.zarr") + " --labels " + p("l.zarr") + " --out " + p("o"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = test::run_sparseleap("render --backend cpu --size 32x32 --mode labels --enable all --volume " + p("i.zarr") +
                           " --labels " + p("l.zarr") + " --out " + p("o2"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(read_exr(p("o") + ".exr").width, 32);
}

TEST_F(ZarrCli, CorruptChunkDuringRenderingIsReportedAndRenderedMissing) {
  auto r = test::run_sparseleap("ingest " + p("n.nrrd") + " " + p("c.zarr") + " --chunk 16 --compressor zstd");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  // Corrupt every stored level-0 chunk of one z layer.
  int corrupted = 0;
  for (const auto& e : fs::recursive_directory_iterator(dir / "c.zarr" / "0" / "2")) {
    if (e.is_regular_file()) {
      test::write_text(e.path(), "not zstd at all");
      ++corrupted;
    }
  }
  ASSERT_GT(corrupted, 0);
  const std::string args = "render --backend cpu --size 48x40 --cache-mb 16 --brick 16 --frames 12 --lod 0 --volume " +
                           p("c.zarr") + " --out " + p("o");
  r = test::run_sparseleap(args);
  EXPECT_EQ(r.exit_code, 4) << r.output;  // the image is written, short of the failed bricks
  EXPECT_TRUE(fs::exists(dir / "o.png"));
  EXPECT_NE(r.output.find("warning: brick failed to load"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("level 0 (array '0') chunk '2/"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("corrupt"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("bricks failed to load after 12 frames"), std::string::npos) << r.output;
  r = test::run_sparseleap(args + " --allow-partial");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  r = test::run_sparseleap(args + " --allow-partial --strict");
  EXPECT_EQ(r.exit_code, 1) << r.output;
}

TEST_F(ZarrCli, IngestErrorsAreOneLineAndLeaveNothing) {
  const auto one_line = [](const test::RunResult& r, const std::string& needle) {
    EXPECT_EQ(r.exit_code, 1) << r.output;
    EXPECT_EQ(lines(r.output), 1) << r.output;
    EXPECT_NE(r.output.find(needle), std::string::npos) << needle << " in " << r.output;
  };
  one_line(test::run_sparseleap("ingest " + p("nope.nrrd") + " " + p("o.zarr")), "nope.nrrd");
  one_line(test::run_sparseleap("ingest " + p("n.nrrd") + " " + p("o.zarr") + " --compressor lzma"), "--compressor");
  one_line(test::run_sparseleap("ingest " + p("n.nrrd") + " " + p("o.zarr") + " --compressor zlib --level 10"), "--level");
  one_line(test::run_sparseleap("ingest " + p("n.nrrd") + " " + p("o.zarr") + " --chunk 9"), "--chunk");
  // A truncated input fails halfway: no store and no temporary directory remain.
  GeneratedVolume g = generate_volume("blobs", ivec3(64, 64, 96), 1);
  write_nrrd(p("b.nrrd"), g.intensity, true);
  fs::resize_file(dir / "b.nrrd", fs::file_size(dir / "b.nrrd") * 2 / 3);
  one_line(test::run_sparseleap("ingest " + p("b.nrrd") + " " + p("o.zarr") + " --chunk 16"), "b.nrrd");
  for (const auto& e : fs::directory_iterator(dir)) {
    EXPECT_NE(e.path().filename().string().rfind(".o.zarr", 0), 0u) << e.path();
  }
  EXPECT_FALSE(fs::exists(dir / "o.zarr"));
  // An existing output needs --force.
  ASSERT_EQ(test::run_sparseleap("ingest " + p("n.nrrd") + " " + p("o.zarr")).exit_code, 0);
  one_line(test::run_sparseleap("ingest " + p("n.nrrd") + " " + p("o.zarr")), "--force");
  EXPECT_EQ(test::run_sparseleap("ingest " + p("n.nrrd") + " " + p("o.zarr") + " --force --compressor none").exit_code, 0);
}

TEST_F(ZarrCli, BadStoresAreOneLineErrors) {
  ASSERT_EQ(test::run_sparseleap("ingest " + p("n.nrrd") + " " + p("s.zarr") + " --chunk 16").exit_code, 0);
  test::write_text(dir / "s.zarr" / "1" / ".zarray", "{ not json");
  for (const std::string& cmd : {std::string("info "), "render --size 8x8 --out " + p("o") + " --volume ",
                                "render --size 8x8 --cache-mb 8 --out " + p("o") + " --volume "}) {
    const test::RunResult r = test::run_sparseleap(cmd + p("s.zarr"));
    EXPECT_EQ(r.exit_code, 1) << r.output;
    EXPECT_EQ(lines(r.output), 1) << r.output;
    EXPECT_NE(r.output.find("s.zarr: level 1 (array '1'): malformed JSON"), std::string::npos) << r.output;
  }
  const test::RunResult r = test::run_sparseleap("info " + p("missing.zarr"));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("missing.zarr"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "o.png"));
}

}  // namespace
}  // namespace sl
