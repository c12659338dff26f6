// scripts/gpu-check without a GPU: --dry-run must run every part that needs none (the CPU renders of every method
// and mode in and out of core, the image comparison on CPU against CPU with one thread, its self-check on two
// images that differ, the CPU bench) and say what it skipped; bad arguments are one line and exit 2; without a GPU
// the real check fails at once, saying so. The GPU half runs only on a machine with an NVIDIA GPU (docs/cuda.md).
#include <gtest/gtest.h>

#include <algorithm>
#include <initializer_list>
#include <string>

#include "tests/test_util.h"

namespace sl {
namespace {

const std::string kScript = std::string(SL_SOURCE_DIR) + "/scripts/gpu-check";

bool have_numpy() { return test::run_shell("/usr/bin/python3 -c 'import numpy' 2>/dev/null").exit_code == 0; }

int count(const std::string& text, const std::string& what) {
  int n = 0;
  for (std::size_t p = text.find(what); p != std::string::npos; p = text.find(what, p + 1)) ++n;
  return n;
}

TEST(GpuCheck, DryRunRendersAndComparesEveryCaseAndSaysWhatItSkipped) {
  if (!have_numpy()) SL_SKIP_OR_FAIL("python3-numpy is missing (scripts/setup installs it)");
  const auto dir = test::scratch_dir();
  const test::RunResult r = test::run_shell(kScript + " --dry-run --quick --sparseleap " +
                                            test::sparseleap_exe().string() + " --out " + dir.string() + " 2>&1");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("dry run: skipped: nvidia-smi, the build for the local GPU architecture, cuda_tests, "
                          "the --backend cuda renders and the CUDA bench"),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("comparison self-check: dvr against mip differs"), std::string::npos) << r.output;
  // 4 methods x 4 modes in core, 2 methods x 4 modes out of core, each identical across thread counts.
  EXPECT_EQ(count(r.output, "  ok   incore_"), 16) << r.output;
  EXPECT_EQ(count(r.output, "  ok   ooc_"), 8) << r.output;
  EXPECT_EQ(count(r.output, "max difference 0 (0 pixels differ)"), 24) << r.output;
  EXPECT_NE(r.output.find("sparseleap (out of core)"), std::string::npos) << r.output;  // the bench table
  EXPECT_NE(r.output.find("gpu-check: dry run passed"), std::string::npos) << r.output;
}

TEST(GpuCheck, BadArgumentsAreOneLineAndExitTwo) {
  const std::string exe = test::sparseleap_exe().string();
  for (const std::string& args : std::initializer_list<std::string>{
           "--dry-run --tolerance -1", "--dry-run --size 0x4", "--dry-run --frames 0", "--dry-run --volume /data/x.nrrd",
           "--dry-run --sparseleap /no/such/sparseleap", "--sparseleap " + exe, "--dry-run --no-such-flag"}) {
    const test::RunResult r = test::run_shell(kScript + " " + args + " 2>&1");
    EXPECT_EQ(r.exit_code, 2) << args << ": " << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << args << ": " << r.output;
    EXPECT_EQ(r.output.rfind("gpu-check: error: ", 0), 0u) << args << ": " << r.output;
  }
}

TEST(GpuCheck, WithoutAnNvidiaDriverTheRealCheckFailsAndPointsToTheDryRun) {
  if (test::run_shell("command -v nvidia-smi >/dev/null").exit_code == 0) GTEST_SKIP() << "this machine has nvidia-smi";
  const auto dir = test::scratch_dir();
  const test::RunResult r = test::run_shell(kScript + " --quick --out " + dir.string() + " 2>&1");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("nvidia-smi not found"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("--dry-run"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace sl
