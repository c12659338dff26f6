// `sparseleap render --lists gl`: the segment lists come from the OpenGL builder (headless EGL) and the
// image is the one the CPU-built lists give (out of core: tests/gl/gl_lists_renderer_test.cpp, where
// loads can be awaited). Skips, saying why, where no GL context can be made (no GL backend, no EGL).
#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>
#include <string>

#include "core/util/image.h"
#include "tests/test_util.h"

namespace sl {
namespace {

void expect_same_image_with_gl_lists(const std::string& args) {
  const auto dir = test::scratch_dir();
  // Under SL_SANITIZE: the program's GL context is destroyed at exit, which unloads Mesa's driver, and
  // the driver's process-lifetime allocations then carry no module name that LeakSanitizer could
  // suppress (tests/gl/gl_test_util.h). They are not ours: leak checking is off for this one run.
  const char* old = std::getenv("ASAN_OPTIONS");
  const std::string saved = old ? old : "";
  setenv("ASAN_OPTIONS", (saved.empty() ? std::string("detect_leaks=0") : saved + ":detect_leaks=0").c_str(), 1);
  const test::RunResult gl = test::run_sparseleap(args + " --lists gl --out " + (dir / "gl").string());
  if (old) {
    setenv("ASAN_OPTIONS", saved.c_str(), 1);
  } else {
    unsetenv("ASAN_OPTIONS");
  }
  if (gl.exit_code != 0 && (gl.output.find("--lists") != std::string::npos)) {
    SL_SKIP_OR_FAIL("no GL list builder here: " + gl.output);
  }
  ASSERT_EQ(gl.exit_code, 0) << gl.output;
  const test::RunResult cpu = test::run_sparseleap(args + " --lists cpu --out " + (dir / "cpu").string());
  ASSERT_EQ(cpu.exit_code, 0) << cpu.output;
  const Image a = read_exr((dir / "gl.exr").string());
  const Image b = read_exr((dir / "cpu.exr").string());
  ASSERT_EQ(a.rgba.size(), b.rgba.size());
  std::size_t differing = 0;
  float alpha = 0.0f;
  for (std::size_t i = 0; i < a.rgba.size(); ++i) {
    differing += std::memcmp(&a.rgba[i], &b.rgba[i], sizeof(vec4)) != 0;
    alpha += b.rgba[i].w;
  }
  EXPECT_EQ(differing, 0u) << args;
  EXPECT_GT(alpha, 1.0f);
}

TEST(ListsCli, GlListsRenderTheCpuListsImageInCore) {
  expect_same_image_with_gl_lists("render --backend cpu --size 64x48 --block 8");
}

TEST(ListsCli, UnknownListBuilderIsOneClearLine) {
  const auto dir = test::scratch_dir();
  const test::RunResult r = test::run_sparseleap("render --lists vulkan --size 8x8 --out " + (dir / "x").string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("--lists"), std::string::npos) << r.output;
  int lines = 0;
  for (char c : r.output) lines += c == '\n';
  EXPECT_EQ(lines, 1) << r.output;
}

}  // namespace
}  // namespace sl
