// The bad-input corpus (bad_input_harness.h): the right blame and the right status. A float volume
// without a finite value, or whose values span more than a float holds, names the volume (no
// transfer function was given to blame); a --cache-mb this machine cannot hold names the option and
// the memory available; an ingest --level outside the codec's range names the range; a 0 that would
// silently mean "not given" (a 0, an empty name) is refused. Option values are refused, never clamped.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "tests/apps/bad_input_harness.h"

namespace sl::bad_input {
namespace {

// A 16³ float volume whose voxel i is values[i % values.size()].
Make float_volume(const std::string& name, std::vector<float> values) {
  return [=](const fs::path& d) {
    Volume v(VolumeDesc{{16, 16, 16}, vec3(1.0f), VoxelType::F32});
    float* p = v.as<float>();
    for (std::size_t i = 0; i < 16 * 16 * 16; ++i) p[i] = values[i % values.size()];
    write_nrrd((d / name).string(), v);
  };
}
// The same as an OME-Zarr store (ingest), read out of core.
Make float_store(std::vector<float> values) {
  return [=](const fs::path& d) {
    float_volume("f.nrrd", values)(d);
    const auto r = test::run_sparseleap("ingest " + (d / "f.nrrd").string() + " " + (d / "s.zarr").string() +
                                        " --chunk 8 --compressor none");
    if (r.exit_code != 0) throw std::runtime_error("case setup: " + r.output);
    fs::remove(d / "f.nrrd");
  };
}

std::vector<Case> status_cases() {
  constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
  constexpr float kInf = std::numeric_limits<float>::infinity();
  constexpr float kMax = std::numeric_limits<float>::max();
  const std::string r = kRender + "--volume v.nrrd";
  const std::string no_finite = "v.nrrd: no finite values";
  const std::string overflows = "v.nrrd: value range [";
  const std::string ooc = kRender + "--volume s.zarr --cache-mb 16 --brick 8 --block 8";
  const std::string ingest = "ingest v.nrrd s.zarr ";
  const auto in = file("v.nrrd", templates().nrrd);
  std::vector<Case> cases = {
      // Float volumes with nothing a default transfer function could span.
      {"status", "all NaN", float_volume("v.nrrd", {kNaN}), r, 1, no_finite},
      {"status", "all +Inf", float_volume("v.nrrd", {kInf}), r, 1, no_finite},
      {"status", "all -Inf", float_volume("v.nrrd", {-kInf}), r, 1, no_finite},
      {"status", "NaN and both infinities", float_volume("v.nrrd", {kNaN, kInf, -kInf}), r, 1, no_finite},
      {"status", "all NaN, mip", float_volume("v.nrrd", {kNaN}), r + " --mode mip", 1, no_finite},
      {"status", "all NaN, iso", float_volume("v.nrrd", {kNaN}), r + " --mode iso", 1, no_finite},
      {"status", "all NaN, octree", float_volume("v.nrrd", {kNaN}), r + " --method octree", 1, no_finite},
      {"status", "-3e38 and 3e38", float_volume("v.nrrd", {-3e38f, 3e38f}), r, 1, overflows},
      {"status", "-3e38, NaN and 3e38", float_volume("v.nrrd", {-3e38f, kNaN, 3e38f}), r, 1, overflows},
      {"status", "the largest floats", float_volume("v.nrrd", {-kMax, kMax}), r, 1, overflows},
      {"status", "-2e38 and 2e38", float_volume("v.nrrd", {-2e38f, 2e38f}), r, 1, overflows},
      {"status", "all NaN, a store out of core", float_store({kNaN}), ooc, 1, "s.zarr: no finite values"},
      {"status", "all +Inf, a store out of core", float_store({kInf}), ooc, 1, "s.zarr: no finite values"},
      {"status", "-3e38 and 3e38, a store out of core", float_store({-3e38f, 3e38f}), ooc, 1, "s.zarr: value range ["},
      // A cache budget this machine cannot hold, and a 0 that would read as "not given".
      {"status", "--cache-mb beyond memory", kNothing, kRenderSmall + "--cache-mb 99999999", 1,
       "--cache-mb: 99999999 MB is more than this machine can hold"},
      {"status", "--cache-mb beyond memory, a store", store("s.zarr", [](const fs::path&) {}),
       kRender + "--volume s.zarr --cache-mb 4000000000", 1, "MB of memory available"},
      {"status", "--cache-mb beyond memory, bench", kNothing,
       "bench --volume builtin:neurites:16x16x16 --size 8x8 --orbit 1 --cache-mb 99999999", 1,
       "--cache-mb: 99999999 MB is more than this machine can hold"},
      {"status", "--cache-mb 0", kNothing, kRenderSmall + "--cache-mb 0", 1, "--cache-mb: must be positive, got 0"},
      // An empty name would read as "not given" (the default volume, ramp, camera; no cache).
      {"status", "--volume empty", kNothing, kRender + "--volume ''", 1, "--volume: the name is empty"},
      {"status", "--labels empty", kNothing, kRenderSmall + "--labels ''", 1, "--labels: the name is empty"},
      {"status", "--tf empty", kNothing, kRenderSmall + "--tf ''", 1, "--tf: the name is empty"},
      {"status", "--camera empty", kNothing, kRenderSmall + "--camera ''", 1, "--camera: the name is empty"},
      {"status", "--disk-cache empty", kNothing, kRenderSmall + "--disk-cache ''", 1, "--disk-cache: the name is empty"},
      {"status", "--cache-mb 0, bench", kNothing, "bench --volume builtin:neurites:16x16x16 --size 8x8 --cache-mb 0", 1,
       "--cache-mb: must be positive, got 0"},
      // ingest: a level outside the codec's range is refused (never clamped or replaced by the default).
      {"status", "zstd level -5", in, ingest + "--compressor zstd --level -5", 1, "--level: level must be 0-22 for zstd, got -5"},
      {"status", "zstd level -1", in, ingest + "--compressor zstd --level -1", 1, "--level: level must be 0-22 for zstd, got -1"},
      {"status", "zstd level 23", in, ingest + "--compressor zstd --level 23", 1, "--level: level must be 0-22 for zstd, got 23"},
      {"status", "zstd level -5, zarr3", in, ingest + "--format zarr3 --compressor zstd --level -5", 1,
       "--level: level must be 0-22 for zstd"},
      {"status", "zstd level -5, sharded", in, ingest + "--format zarr3 --shard 2 --compressor zstd --level -5", 1,
       "--level: level must be 0-22 for zstd"},
      {"status", "zlib level -1", in, ingest + "--compressor zlib --level -1", 1, "--level: level must be 0-9 for zlib, got -1"},
      {"status", "zlib level 10", in, ingest + "--compressor zlib --level 10", 1, "--level: level must be 0-9 for zlib, got 10"},
      {"status", "gzip level -3", in, ingest + "--compressor gzip --level -3", 1, "--level: level must be 0-9 for gzip, got -3"},
      {"status", "gzip level 10", in, ingest + "--format zarr3 --compressor gzip --level 10", 1,
       "--level: level must be 0-9 for gzip, got 10"},
      {"status", "blosc-zstd level -1", in, ingest + "--compressor blosc-zstd --level -1", 1,
       "--level: level must be 0-9 for blosc-zstd, got -1"},
      {"status", "blosc-lz4 level 10", in, ingest + "--compressor blosc-lz4 --level 10", 1,
       "--level: level must be 0-9 for blosc-lz4, got 10"},
      {"status", "blosc-zlib level 99", in, ingest + "--compressor blosc-zlib --level 99", 1,
       "--level: level must be 0-9 for blosc-zlib, got 99"},
      {"status", "default blosc-zstd, level -2", in, ingest + "--level -2", 1, "--level: level must be 0-9 for blosc-zstd"},
      {"status", "none with a level", in, ingest + "--compressor none --level 3", 1,
       "--level: the compressor none takes no level"},
      {"status", "none with level 0", in, ingest + "--compressor none --level 0", 1,
       "--level: the compressor none takes no level"},
      {"status", "a level beyond int", in, ingest + "--compressor zstd --level 99999999999", 2, "--level"},
  };
  return cases;
}

TEST(BadInputCorpus, BlameAndStatus) { run_corpus(status_cases()); }

}  // namespace
}  // namespace sl::bad_input
