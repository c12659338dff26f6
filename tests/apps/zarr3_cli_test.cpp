// Zarr v3 / OME-Zarr 0.5 end to end through the `sparseleap` executable: a v2 store written by
// `ingest`, copied to a sharded v3 store by zarr-python 3, renders byte for byte the same frames in
// core and out of core; `info` reports the codecs; a bad v3 store is one line naming the file.
#include <gtest/gtest.h>

#include <filesystem>

#include "cache/formats/nrrd/nrrd.h"
#include "core/scene/generate.h"
#include "tests/cache/formats/zarr_test_util.h"
#include "tests/test_util.h"

namespace sl {
namespace {

namespace fs = std::filesystem;

class Zarr3Cli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir = test::scratch_dir();
    GeneratedVolume g = generate_volume("neurites", ivec3(72, 64, 80), 3);
    write_nrrd((dir / "n.nrrd").string(), g.intensity);
    write_nrrd((dir / "n_labels.nrrd").string(), g.labels);
  }
  std::string p(const char* name) const { return (dir / name).string(); }
  // Renders `volume` with `args`; returns the PNG's bytes.
  std::vector<std::byte> render(const std::string& volume, const std::string& args, const char* out) const {
    const auto r = test::run_sparseleap("render --backend cpu --size 48x40 " + args + " --volume " + volume + " --out " + p(out));
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return test::read_bytes(dir / (std::string(out) + ".png"));
  }
  fs::path dir;
};

TEST_F(Zarr3Cli, ShardedCopyRendersLikeTheV2Store) {
  SL_REQUIRE_PEER3();
  auto r = test::run_sparseleap("ingest " + p("n.nrrd") + " " + p("v2.zarr") + " --chunk 16 --labels " + p("n_labels.nrrd"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::string out;
  ASSERT_EQ(test::run_peer3("convert " + p("v2.zarr") + " " + p("v3.zarr") +
                                " --chunks 8,8,8 --shards 32,32,32 --compressor blosc-zstd --crc",
                            &out),
            0)
      << out;

  r = test::run_sparseleap("info " + p("v3.zarr"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  for (const char* s : {"Zarr v3", "72 x 64 x 80", "shards 32x32x32", "sharding_indexed (inner chunks 8x8x8",
                        "blosc (zstd", "crc32c", "index at end", "shards stored", "labels/labels: u16"}) {
    EXPECT_NE(r.output.find(s), std::string::npos) << s << " in " << r.output;
  }

  // The mean levels: the peer's copy has only those (ingest's max levels are its own extension).
  const std::string ooc = "--cache-mb 16 --brick 16 --frames 20 --pyramid mean";
  for (const std::string& args : {std::string(""), ooc, ooc + " --mode labels --enable all", std::string("--mode mip")}) {
    SCOPED_TRACE(args);
    const auto a = render(p("v2.zarr"), args, "a");
    const auto b = render(p("v3.zarr"), args, "b");
    ASSERT_FALSE(a.empty());
    EXPECT_EQ(a, b);
  }
}

TEST_F(Zarr3Cli, BadStoreIsOneLineNamingTheStore) {
  SL_REQUIRE_PEER3();
  std::string out;
  ASSERT_EQ(test::run_peer3("make " + p("s.zarr") + " " + p("exp") +
                                " --dtype uint8 --shape 16,16,16 --chunks 8,8,8 --levels 1 --compressor zstd",
                            &out),
            0)
      << out;
  std::string meta = test::read_text(dir / "s.zarr" / "0" / "zarr.json");
  const std::size_t at = meta.find("\"zstd\"");
  ASSERT_NE(at, std::string::npos) << meta;
  meta.replace(at, 6, "\"lzma\"");
  test::write_text(dir / "s.zarr" / "0" / "zarr.json", meta);
  for (const char* cmd : {"info ", "render --backend cpu --size 16x16 --volume "}) {
    const auto r = test::run_sparseleap(std::string(cmd) + p("s.zarr"));
    EXPECT_NE(r.exit_code, 0);
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    EXPECT_NE(r.output.find(p("s.zarr")), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("level 0 (array '0'): codec 'lzma' is not supported"), std::string::npos) << r.output;
  }
}

}  // namespace
}  // namespace sl
