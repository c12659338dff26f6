// The bad-input corpus (bad_input_harness.h): OME-Zarr stores; and a label store with a corrupt chunk
// rendered out of core.
#include <gtest/gtest.h>


#include "tests/apps/bad_input_harness.h"

namespace sl::bad_input {
namespace {

std::vector<Case> zarr_cases() {
  const std::string r = kRender + "--volume s.zarr";
  const std::string ooc = r + " --cache-mb 16 --brick 8 --block 8";
  const auto zarray = [](const std::string& from, const std::string& to) {
    return store("s.zarr", [=](const fs::path& s) { edit(s / "0" / ".zarray", from, to); });
  };
  const auto zarray_raw = [](const std::string& from, const std::string& to) {
    return store("s.zarr", [=](const fs::path& s) { edit(s / "0" / ".zarray", from, to); }, true);
  };
  const auto chunk = [](std::function<void(const fs::path&)> fn, bool raw = false) {
    return store("s.zarr", [=](const fs::path& s) { fn(first_chunk(s / "0")); }, raw);
  };
  return {
      {"zarr", "no .zarray", store("s.zarr", [](const fs::path& s) { fs::remove(s / "0" / ".zarray"); }), r, 1, "s.zarr"},
      {"zarr", "empty .zarray", store("s.zarr", [](const fs::path& s) { write_bytes(s / "0" / ".zarray", ""); }), r, 1,
       "s.zarr"},
      {"zarr", ".zarray truncated", store("s.zarr", [](const fs::path& s) { truncate_to(s / "0" / ".zarray", 30); }), r,
       1, "s.zarr"},
      {"zarr", ".zarray is a directory",
       store("s.zarr", [](const fs::path& s) { fs::remove(s / "0" / ".zarray"); fs::create_directory(s / "0" / ".zarray"); }),
       r, 1, "s.zarr"},
      {"zarr", "negative shape", zarray("\"shape\": [\n    16", "\"shape\": [\n    -16"), r, 1, "s.zarr"},
      {"zarr", "zero shape", zarray("\"shape\": [\n    16", "\"shape\": [\n    0"), r, 1, "s.zarr"},
      {"zarr", "absurd shape", zarray("\"shape\": [\n    16", "\"shape\": [\n    1000000000000"), r, 1, "s.zarr"},
      {"zarr", "shape overflows a double", zarray("\"shape\": [\n    16", "\"shape\": [\n    1e999"), r, 1, "s.zarr"},
      {"zarr", "two axes", zarray("\"shape\": [\n    16,", "\"shape\": ["), r, 1, "s.zarr"},
      {"zarr", "zero chunks", zarray("\"chunks\": [\n    8", "\"chunks\": [\n    0"), r, 1, "s.zarr"},
      {"zarr", "absurd chunks", zarray("\"chunks\": [\n    8", "\"chunks\": [\n    2000000000"), r, 1, "s.zarr"},
      {"zarr", "float64", zarray("|u1", "<f8"), r, 1, "s.zarr"},
      {"zarr", "int16", zarray("|u1", "<i2"), r, 1, "s.zarr"},
      {"zarr", "control bytes in dtype", zarray("|u1", "\\u0007\\u001b"), r, 1, "s.zarr"},
      {"zarr", "Fortran order", zarray("\"order\": \"C\"", "\"order\": \"F\""), r, 1, "s.zarr"},
      {"zarr", "a filter", zarray("\"filters\": null", "\"filters\": [{\"id\": \"delta\"}]"), r, 1, "s.zarr"},
      {"zarr", "unknown compressor", zarray_raw("\"compressor\": null", "\"compressor\": {\"id\": \"lzma\"}"), r, 1,
       "s.zarr"},
      {"zarr", "bad separator", zarray("\"dimension_separator\": \"/\"", "\"dimension_separator\": \"|\""), r, 1,
       "s.zarr"},
      {"zarr", "bad fill value", zarray("\"fill_value\": 0.0", "\"fill_value\": \"lots\""), r, 1, "s.zarr"},
      {"zarr", "zarr v3", store("s.zarr", [](const fs::path& s) {
         fs::remove(s / ".zattrs");
         fs::remove(s / ".zgroup");
         write_bytes(s / "zarr.json", "{\"zarr_format\": 3, \"node_type\": \"group\"}");
       }), r, 1, "s.zarr"},
      {"zarr", "malformed .zattrs", store("s.zarr", [](const fs::path& s) { truncate_to(s / ".zattrs", 50); }), r, 1,
       "s.zarr"},
      {"zarr", "deeply nested .zattrs",
       store("s.zarr", [](const fs::path& s) { write_bytes(s / ".zattrs", "{\"multiscales\": " + nest(100000) + "}"); }),
       r, 1, "s.zarr"},
      {"zarr", "no datasets", store("s.zarr", [](const fs::path& s) {
         write_bytes(s / ".zattrs", "{\"multiscales\": [{\"version\": \"0.4\", \"datasets\": []}]}");
       }), r, 1, "s.zarr"},
      {"zarr", "dataset path missing", store("s.zarr", [](const fs::path& s) { edit(s / ".zattrs", "\"path\": \"1\"", "\"path\": \"7\""); }),
       r, 1, "s.zarr"},
      {"zarr", "level ratio 3", store("s.zarr", [](const fs::path& s) {
         edit(s / "1" / ".zarray", "\"shape\": [\n    8,\n    8,\n    8", "\"shape\": [\n    6,\n    6,\n    6");
       }), r, 1, "s.zarr"},
      {"zarr", "dtype changes between levels", store("s.zarr", [](const fs::path& s) { edit(s / "1" / ".zarray", "|u1", "<u2"); }),
       r, 1, "s.zarr"},
      {"zarr", "chunk truncated (in core)", chunk([](const fs::path& c) { truncate_to(c, fs::file_size(c) / 2); }), r,
       1, "s.zarr"},
      {"zarr", "chunk garbage (in core)", chunk([](const fs::path& c) { write_bytes(c, Bytes(300, '\x42')); }), r, 1,
       "s.zarr"},
      {"zarr", "chunk of the wrong size (raw)", chunk([](const fs::path& c) { truncate_to(c, 100); }, true), r, 1,
       "s.zarr"},
      {"zarr", "chunk too long (raw)", chunk([](const fs::path& c) { write_bytes(c, Bytes(513, '\x01')); }, true), r, 1,
       "s.zarr"},
      {"zarr", "chunk is a directory", chunk([](const fs::path& c) { fs::remove(c); fs::create_directory(c); }), r, 1,
       "s.zarr"},
      {"zarr", "labels of float type",
       store("s.zarr", [](const fs::path& s) {
         edit(s / "labels" / "labels" / "0" / ".zarray", "<u2", "<f4");
         edit(s / "labels" / "labels" / "1" / ".zarray", "<u2", "<f4");
       }), ooc, 1, "s.zarr"},
      {"zarr", "labels of other dims",
       store("s.zarr", [](const fs::path& s) {
         edit(s / "labels" / "labels" / "0" / ".zarray", "\"shape\": [\n    16", "\"shape\": [\n    15");
       }), ooc, 1, "s.zarr"},
      {"zarr", "labels .zattrs malformed",
       store("s.zarr", [](const fs::path& s) { truncate_to(s / "labels" / ".zattrs", 10); }), ooc, 1, "s.zarr"},
      {"zarr", "out of core: no .zarray", store("s.zarr", [](const fs::path& s) { fs::remove(s / "0" / ".zarray"); }),
       ooc, 1, "s.zarr"},
      {"zarr", "out of core: unknown dtype", zarray("|u1", "<c8"), ooc, 1, "s.zarr"},
      {"zarr", "--labels store of other dims",
       [](const fs::path& d) {
         fs::copy(templates().store, d / "s.zarr", fs::copy_options::recursive);
         fs::copy(templates().store, d / "l.zarr", fs::copy_options::recursive);
         edit(d / "l.zarr" / "0" / ".zarray", "\"shape\": [\n    16", "\"shape\": [\n    12");
       }, ooc + " --labels l.zarr", 1, "l.zarr"},
      {"zarr", "info of a bad store", zarray("|u1", "<f8"), "info s.zarr", 1, "s.zarr"},
      {"zarr", "info --stats of a corrupt chunk", chunk([](const fs::path& c) { write_bytes(c, Bytes(300, '\x42')); }),
       "info --stats s.zarr", 1, "s.zarr"},
      {"zarr", ".zarray of 100 MiB", store("s.zarr", [](const fs::path& s) {
         fs::resize_file(s / "0" / ".zarray", std::uintmax_t(100) << 20);  // sparse
       }), r, 1, "s.zarr: level 0 (array '0'): '.zarray' is 100 MiB"},
      {"zarr", "not a store at all", [](const fs::path& d) { fs::create_directory(d / "s.zarr"); }, r, 1, "s.zarr"},
  };
}

TEST(BadInputCorpus, Zarr) { run_corpus(zarr_cases()); }

// A label store without the `max_label` attribute (not written by our ingest) and with a corrupt
// chunk: the max-label scan skips the chunk, and out of core the render goes on with the brick
// reported and rendered as missing, instead of stopping before the first frame.
TEST(LabelStore, CorruptChunkWithoutMaxLabelRendersOutOfCore) {
  const fs::path dir = test::scratch_dir();
  GeneratedVolume g = generate_volume("neurites", ivec3(32), 1);
  write_nrrd((dir / "v.nrrd").string(), g.intensity);
  write_nrrd((dir / "l.nrrd").string(), g.labels);
  test::RunResult r = test::run_sparseleap("ingest " + (dir / "v.nrrd").string() + " " + (dir / "s.zarr").string() +
                                           " --labels " + (dir / "l.nrrd").string() + " --chunk 8 --compressor zstd");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const fs::path attrs = dir / "s.zarr" / "labels" / "labels" / ".zattrs";
  std::string a = test::read_text(attrs);
  const auto at = a.find(",\n  \"sparseleap\"");
  ASSERT_NE(at, std::string::npos) << a;
  test::write_text(attrs, a.substr(0, at) + "\n}\n");
  const fs::path chunk = first_chunk(dir / "s.zarr" / "labels" / "labels" / "0");
  test::write_text(chunk, "not zstd at all");
  const std::string out = (dir / "o").string();
  r = test::run_sparseleap("render --backend cpu --size 32x32 --cache-mb 16 --brick 8 --block 8 --lod 0 --frames 40 "
                           "--allow-partial --mode labels --enable all --volume " + (dir / "s.zarr").string() + " --out " + out +
                           " --stats-json " + (dir / "o.json").string());
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(out + ".png"));
  // Bricks load on worker threads, so on a busy machine the one holding the chunk may still be
  // pending after the last frame; once every brick is resolved (converged), it has been reported.
  if (test::read_text(dir / "o.json").find("\"converged_at_frame\": -1") == std::string::npos) {
    EXPECT_NE(r.output.find("warning: brick failed to load"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("corrupt"), std::string::npos) << r.output;
  }
  // In core there is no fault path: the whole label level is read, and the chunk is the error.
  r = test::run_sparseleap("render --backend cpu --size 8x8 --mode labels --volume " + (dir / "s.zarr").string() +
                           " --out " + (dir / "x").string());
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("chunk '"), std::string::npos) << r.output;
}

// The out-of-core warning for a brick that failed to load escapes control bytes as the error line does
// (core/util/printable.h), here from the store's name, so it stays one line and cannot drive the terminal.
TEST(OutOfCoreWarning, ControlBytesInTheReasonAreEscaped) {
  const fs::path dir = test::scratch_dir();
  GeneratedVolume g = generate_volume("neurites", ivec3(32), 1);
  write_nrrd((dir / "v.nrrd").string(), g.intensity);
  const fs::path store = dir / "s\x1b[2J.zarr";
  test::RunResult r = test::run_sparseleap("ingest " + (dir / "v.nrrd").string() + " '" + store.string() +
                                           "' --chunk 8 --compressor zstd");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  test::write_text(first_chunk(store / "0"), "not zstd at all");
  // stderr alone (the summary on stdout names the store as given).
  r = test::run_shell(test::sparseleap_exe().string() + " render --backend cpu --size 32x32 --cache-mb 16 --brick 8 "
                      "--block 8 --lod 0 --frames 40 --allow-partial --volume '" + store.string() + "' --out " + (dir / "o").string() +
                      " --stats-json " + (dir / "o.json").string() + " 2>&1 >/dev/null");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(r.output.find('\x1b'), std::string::npos) << r.output;
  // As above: the warning is certain only once every brick is resolved.
  if (test::read_text(dir / "o.json").find("\"converged_at_frame\": -1") == std::string::npos) {
    EXPECT_NE(r.output.find("warning: brick failed to load, rendered as missing: " + dir.string() + "/s\\x1b[2J.zarr"),
              std::string::npos)
        << r.output;
  }
}

}  // namespace
}  // namespace sl::bad_input
