// `--backend cuda` and `--backend auto` end to end, in core and out of core. On a machine without a
// CUDA device (every development and CI machine so far): cuda is one clear error line, auto falls back
// to the CPU with a notice. With a device the same commands must render on it (not yet seen run).
#include <gtest/gtest.h>

#include <filesystem>

#include "cuda/cuda_renderer.h"
#include "tests/test_util.h"

namespace sl {
namespace {

int count_lines(const std::string& s) {
  int n = 0;
  for (char c : s) n += c == '\n';
  return n;
}

bool have_device() { return cuda::query_devices().count > 0; }

void expect_cuda_backend(const std::string& args) {
  const auto dir = test::scratch_dir();
  const std::string out = (dir / "f").string();
  const test::RunResult r = test::run_sparseleap(args + " --backend cuda --out " + out);
  if (have_device()) {
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find(" cuda "), std::string::npos) << r.output;
    return;
  }
  EXPECT_NE(r.exit_code, 0) << r.output;
  EXPECT_EQ(count_lines(r.output), 1) << r.output;
  EXPECT_EQ(r.output.rfind("sparseleap: ", 0), 0u) << r.output;
  EXPECT_NE(r.output.find("--backend"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("no CUDA device"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(out + ".png"));
}

void expect_auto_backend(const std::string& args) {
  const auto dir = test::scratch_dir();
  const std::string out = (dir / "f").string();
  const test::RunResult r = test::run_sparseleap(args + " --backend auto --out " + out);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(std::filesystem::exists(out + ".png"));
  if (!have_device()) {
    EXPECT_NE(r.output.find("no CUDA device"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("using the CPU backend"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find(" cpu "), std::string::npos) << r.output;
  }
}

TEST(CudaCli, InCoreCudaIsOneClearLineWithoutADeviceAndAutoFallsBack) {
  for (const char* method : {"none", "bbox", "octree", "sparseleap"}) {
    expect_cuda_backend(std::string("render --size 32x24 --method ") + method);
  }
  expect_auto_backend("render --size 32x24 --method octree");
}

TEST(CudaCli, OutOfCoreCudaIsOneClearLineWithoutADeviceAndAutoFallsBack) {
  expect_cuda_backend("render --volume procedural:neurites:96x96x96 --cache-mb 64 --size 32x24");
  expect_auto_backend("render --volume procedural:neurites:96x96x96 --cache-mb 64 --size 32x24");
}

TEST(CudaCli, BadInputStaysTheOnlyLineUnderAuto) {
  const auto dir = test::scratch_dir();
  const test::RunResult r =
      test::run_sparseleap("render --backend auto --size 0x0 --out " + (dir / "f").string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_EQ(count_lines(r.output), 1) << r.output;
  EXPECT_NE(r.output.find("--size"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace sl
