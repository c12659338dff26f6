// The bad-input corpus (bad_input_harness.h): output paths (missing folders, directories, FIFOs, full
// devices); and device outputs that are streams.
#include <gtest/gtest.h>


#include "tests/apps/bad_input_harness.h"

namespace sl::bad_input {
namespace {

std::vector<Case> output_cases() {
  const std::string r = kRenderSmall;
  const Templates& t = templates();
  const auto dirs = [](std::vector<std::string> names) {
    return [=](const fs::path& d) {
      for (const auto& n : names) fs::create_directories(d / n);
    };
  };
  const auto fifo = [](const std::string& name) {
    return [=](const fs::path& d) { ASSERT_EQ(::mkfifo((d / name).c_str(), 0600), 0); };
  };
  const std::string b = "bench --volume builtin:neurites:16x16x16 --size 8x8 --orbit 1 --methods none ";
  return {
      {"output", "missing folder", kNothing, "render --size 8x8 --volume builtin:neurites:16x16x16 --out no/out", 1,
       "no/out"},
      {"output", "out.exr is a directory", dirs({"out.exr"}), r, 1, "out.exr"},
      {"output", "out.png is a directory", dirs({"out.png"}), r, 1, "out.png"},
      {"output", "stats JSON is a directory", dirs({"s.json"}), r + "--stats-json s.json", 1, "s.json"},
      {"output", "stats JSON in a missing folder", kNothing, r + "--stats-json no/s.json", 1, "no/s.json"},
      {"output", "stats JSON is a FIFO without reader", fifo("s.json"), r + "--stats-json s.json", 1, "s.json"},
      {"output", "--out a full device", full_device("full"),
       "render --backend cpu --size 8x8 --volume builtin:neurites:16x16x16 --out full", 1,
       "full: cannot write file: No space left on device"},
      // Larger than stdio's buffer, so libpng's own writes fail (not only the final flush): the reason
      // is still the errno, in the one line.
      {"output", "PNG to a full device", full_device("full.png"),
       "render --backend cpu --size 512x512 --volume builtin:neurites:16x16x16 --out full", 1,
       "full.png: cannot write PNG: No space left on device"},
      {"output", "--stats-json a full device", full_device("full"), r + "--stats-json full", 1,
       "full: cannot write file: No space left on device"},
      {"output", "bench --csv is a directory", dirs({"b.csv"}), b + "--csv b.csv --json b.json", 1, "b.csv"},
      {"output", "bench --json is a directory", dirs({"b.json"}), b + "--csv b.csv --json b.json", 1, "b.json"},
      {"output", "bench --json a full device", full_device("full"), b + "--csv b.csv --json full", 1,
       "full: cannot write file: No space left on device"},
      {"output", "gen into a missing folder", kNothing, "gen blobs --dims 8x8x8 --out no/g.nrrd", 1, "no/g.nrrd"},
      {"output", "gen labels into a missing folder", kNothing,
       "gen blobs --dims 8x8x8 --out g.nrrd --labels-out no/l.nrrd", 1, "no/l.nrrd"},
      {"output", "gen labels output is a directory", dirs({"l.nrrd"}),
       "gen blobs --dims 8x8x8 --out g.nrrd --labels-out l.nrrd", 1, "l.nrrd"},
      {"output", "gen detached data is a directory", dirs({"g.raw"}), "gen blobs --dims 8x8x8 --out g.nhdr", 1, "g.nhdr"},
      {"output", "ingest output exists", both(file("v.nrrd", t.nrrd), dirs({"s.zarr"})), "ingest v.nrrd s.zarr", 1,
       "s.zarr"},
      {"output", "ingest output in a missing folder", file("v.nrrd", t.nrrd), "ingest v.nrrd no/s.zarr", 1, "no/s.zarr"},
      {"output", "ingest output is a file", both(file("v.nrrd", t.nrrd), file("s.zarr", "keep me")),
       "ingest v.nrrd s.zarr", 1, "s.zarr"},
      {"output", "ingest output a device, --force", both(file("v.nrrd", t.nrrd), full_device("full")),
       "ingest v.nrrd full --force", 1, "full: exists and is not a folder"},
      {"output", "ingest output a file, --force", both(file("v.nrrd", t.nrrd), file("s.zarr", "keep me")),
       "ingest v.nrrd s.zarr --force", 1, "s.zarr: exists and is not a folder"},
  };
}

TEST(BadInputCorpus, Output) { run_corpus(output_cases()); }

// Outputs that are devices are streams (core/util/atomic_file.h): /dev/null takes the images and the stats
// and stays /dev/null; nothing appears beside it.
TEST(OutputStreams, DevNullTakesEveryOutput) {
  const fs::path dir = test::scratch_dir();
  test::RunResult r = test::run_sparseleap("render --backend cpu --size 16x16 --volume builtin:neurites:16x16x16 "
                                           "--out /dev/null --stats-json /dev/null");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("-> /dev/null, /dev/null"), std::string::npos) << r.output;
  r = test::run_sparseleap("bench --volume builtin:neurites:16x16x16 --size 8x8 --orbit 1 --methods none --csv "
                           "/dev/null --json /dev/null");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(fs::status("/dev/null").type(), fs::file_type::character);
  EXPECT_FALSE(fs::exists("/dev/null.png"));
  EXPECT_FALSE(fs::exists("/dev/null.exr"));
  // A pipe as the stats file: the JSON arrives through it.
  r = test::run_shell(test::sparseleap_exe().string() + " render --backend cpu --size 8x8 --volume "
                      "builtin:neurites:16x16x16 --out " + (dir / "o").string() + " --stats-json /dev/stdout 2>&1 | cat");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("\"raycast\""), std::string::npos) << r.output;
}

}  // namespace
}  // namespace sl::bad_input
