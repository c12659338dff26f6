// The viewer as a person sees it: a real window under Xvfb (Mesa's software GL), the built-in data
// set rendered for a few frames, and the saved screenshot checked. Each test suite starts its own
// Xvfb with -displayfd, so the server picks a free display number and parallel runs never collide.
#include <gtest/gtest.h>

#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <set>
#include <string>

#include "core/scene/camera.h"
#include "core/scene/camera_path.h"
#include "core/util/image.h"
#include "tests/test_util.h"

namespace sl::test {
namespace {

constexpr int kCanvasW = 320;
constexpr int kCanvasH = 240;
const std::string kSmall = "--backend cpu --volume builtin:neurites:64x64x64 --size 320x240";

bool on_path(const std::string& exe) {
  const char* path = std::getenv("PATH");
  std::string dirs = path ? path : "/usr/bin:/bin";
  std::size_t pos = 0;
  while (pos <= dirs.size()) {
    const std::size_t colon = dirs.find(':', pos);
    const std::string dir = dirs.substr(pos, colon == std::string::npos ? std::string::npos : colon - pos);
    if (!dir.empty() && access((dir + "/" + exe).c_str(), X_OK) == 0) return true;
    if (colon == std::string::npos) break;
    pos = colon + 1;
  }
  return false;
}

// Runs sparseleap with DISPLAY set as given ("" = unset), capturing stdout and stderr.
RunResult run_with_display(const std::string& display, const std::string& args) {
  std::string env = display.empty() ? "env -u DISPLAY -u WAYLAND_DISPLAY " : "env DISPLAY=" + display + " ";
  // Under SL_SANITIZE: Mesa's software driver is unloaded at exit with allocations LeakSanitizer can
  // only attribute to an unknown module (no usable stack), so a windowed run cannot be leak-checked.
  // Every other AddressSanitizer check stays on; the viewer's own state is leak-checked in-process
  // by the unit tests of this suite.
  if (const char* asan = std::getenv("ASAN_OPTIONS"); asan && !display.empty()) {
    env += "ASAN_OPTIONS='" + std::string(asan) + ":detect_leaks=0' ";
  }
  return run_shell(env + sparseleap_exe().string() + " " + args + " 2>&1");
}

class ViewerWindow : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { start(); }

  // Runs the viewer on this suite's Xvfb. A window that cannot open because the display is not
  // reachable (seen once in a CI run, on :0 beside other tests' servers; the cause is not known) is
  // retried once on a fresh server, saying so on stderr; every other failure is the test's.
  static RunResult run_view(const std::string& args) {
    RunResult r = run_with_display(display_, args);
    if (r.exit_code != 0 && r.output.find("cannot open a window") != std::string::npos) {
      const bool alive = pid_ > 0 && waitpid(pid_, nullptr, WNOHANG) == 0;
      std::fprintf(stderr, "viewer_window_test: display %s not reachable (its Xvfb %s); retrying once on a new server\n",
                   display_.c_str(), alive ? "still runs" : "has exited");
      if (!alive) pid_ = -1;
      stop();
      start();
      if (start_error_.empty() && skip_reason_.empty()) r = run_with_display(display_, args);
    }
    return r;
  }

  static void start() {
#ifndef SL_HAVE_VIEWER
    skip_reason_ = "this build has no viewer (GLFW, OpenGL or Dear ImGui not found at configure time)";
    return;
#endif
    if (!on_path("Xvfb")) {
      skip_reason_ = "Xvfb not found (install the xvfb package; scripts/setup does)";
      return;
    }
    int fds[2];
    if (pipe(fds) != 0) {
      skip_reason_ = "pipe() failed";
      return;
    }
    pid_ = fork();
    if (pid_ == 0) {
      close(fds[0]);
      if (FILE* null = std::freopen("/dev/null", "w", stderr)) (void)null;
      const std::string fd = std::to_string(fds[1]);
      execlp("Xvfb", "Xvfb", "-displayfd", fd.c_str(), "-screen", "0", "1280x1024x24", "-nolisten", "tcp",
             static_cast<char*>(nullptr));
      _exit(127);
    }
    close(fds[1]);
    // Xvfb writes the display number it chose once it accepts connections.
    std::string number;
    pollfd p{fds[0], POLLIN, 0};
    while (poll(&p, 1, 15000) > 0) {
      char c = 0;
      if (read(fds[0], &c, 1) != 1 || c == '\n') break;
      number += c;
    }
    close(fds[0]);
    if (number.empty()) {
      stop();
      // Xvfb is installed but did not start: that is a failure, not a reason to skip.
      start_error_ = "Xvfb did not report a display within 15 s";
      return;
    }
    display_ = ":" + number;
  }

  static void TearDownTestSuite() { stop(); }

  static void stop() {
    if (pid_ > 0) {
      kill(pid_, SIGTERM);
      waitpid(pid_, nullptr, 0);
    }
    pid_ = -1;
  }

  void SetUp() override {
    if (!skip_reason_.empty()) SL_SKIP_OR_FAIL(skip_reason_);
    ASSERT_TRUE(start_error_.empty()) << start_error_;
  }

  static inline pid_t pid_ = -1;
  static inline std::string display_;
  static inline std::string skip_reason_;
  static inline std::string start_error_;
};

// Pixels of the rendered canvas: the window's right-most kCanvasW x kCanvasH (the panel is at left).
struct Canvas {
  const Image& img;
  int x0() const { return img.width - kCanvasW; }
  vec4 at(int x, int y) const { return img.at(x0() + x, y); }
};

double lit_fraction(const Canvas& c) {
  int lit = 0;
  for (int y = 0; y < kCanvasH; ++y)
    for (int x = 0; x < kCanvasW; ++x) lit += (c.at(x, y).r + c.at(x, y).g + c.at(x, y).b) > 0.05f;
  return double(lit) / double(kCanvasW * kCanvasH);
}

std::size_t distinct_colours(const Image& img, int x0, int x1) {
  std::set<std::uint32_t> seen;
  for (int y = 0; y < img.height; ++y)
    for (int x = x0; x < x1; ++x) {
      const vec4 c = img.at(x, y) * 255.0f;
      seen.insert(std::uint32_t(c.r) << 16 | std::uint32_t(c.g) << 8 | std::uint32_t(c.b));
    }
  return seen.size();
}

TEST_F(ViewerWindow, RendersTheBuiltInDataSetAndSavesANonBlankScreenshot) {
  const auto dir = scratch_dir();
  const std::string shot = (dir / "view.png").string();
  const RunResult r = run_view("view " + kSmall + " --screenshot " + shot + " --frames 3");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("view: 3 frames"), std::string::npos) << r.output;
  const Image img = read_png(shot);
  ASSERT_GE(img.width, kCanvasW + 100);  // canvas plus the control panel
  ASSERT_EQ(img.height, kCanvasH);
  // The canvas shows the neurites (lit, many colours) and the panel shows widgets and text.
  EXPECT_GT(lit_fraction(Canvas{img}), 0.02);
  EXPECT_GT(distinct_colours(img, img.width - kCanvasW, img.width), 50u);
  EXPECT_GT(distinct_colours(img, 0, img.width - kCanvasW), 10u);
  EXPECT_FALSE(std::filesystem::exists(shot + ".tmp"));
}

TEST_F(ViewerWindow, DepthComplexityViewsOfOctreeAndSparseLeapDiffer) {
  const auto dir = scratch_dir();
  Image img[2];
  const char* methods[2] = {"octree", "sparseleap"};
  for (int i = 0; i < 2; ++i) {
    const std::string shot = (dir / (std::string(methods[i]) + ".png")).string();
    // --no-stats: the overlay would cover part of the canvas compared here.
    const RunResult r = run_view("view " + kSmall + " --method " + methods[i] +
                                                       " --view depth-complexity --no-stats --screenshot " + shot);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    img[i] = read_png(shot);
    ASSERT_EQ(img[i].height, kCanvasH);
    EXPECT_GT(lit_fraction(Canvas{img[i]}), 0.02) << methods[i];
  }
  ASSERT_EQ(img[0].width, img[1].width);
  int differing = 0;
  const Canvas a{img[0]}, b{img[1]};
  for (int y = 0; y < kCanvasH; ++y)
    for (int x = 0; x < kCanvasW; ++x) differing += glm::length(a.at(x, y) - b.at(x, y)) > 0.02f;
  EXPECT_GT(differing, kCanvasW * kCanvasH / 50) << "depth-complexity images of octree and sparseleap are alike";
}

TEST_F(ViewerWindow, ScriptedFramesWithoutScreenshotReportFrameTimes) {
  const RunResult r = run_view("view " + kSmall + " --frames 4 --spin 10 --method octree");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("view: 4 frames"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("octree"), std::string::npos) << r.output;
}

TEST_F(ViewerWindow, OutOfCoreViewStreamsBricksAndConverges) {
  const auto dir = scratch_dir();
  const std::string shot = (dir / "ooc.png").string();
  const RunResult r =
      run_view("view " + kSmall + " --cache-mb 16 --brick 16 --frames 8 --screenshot " + shot);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("converged at frame"), std::string::npos) << r.output;
  const Image img = read_png(shot);
  EXPECT_GT(lit_fraction(Canvas{img}), 0.02);
}

// Progressive rendering: a replayed path is shown coarse while it moves (a 1 ms budget forces coarse
// levels), then the last view is refined, and what stays on screen is byte for byte the PNG `render`
// writes for that view.
TEST_F(ViewerWindow, TheStillFrameAfterCoarseFramesIsTheRenderImage) {
  const auto dir = scratch_dir();
  const std::string path_file = (dir / "orbit.json").string();
  write_text(path_file, camera_path_to_json(orbit_path(vec3(64.0f), 5)));
  const std::string shot = (dir / "still.png").string();
  const RunResult r = run_view(
      "view " + kSmall + " --path " + path_file + " --frame-budget-ms 1 --no-stats --screenshot " + shot);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("view: 5 frames"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("frames/s, pixels 1/"), std::string::npos) << r.output;  // the moving frames were coarse
  EXPECT_NE(r.output.find("refined in"), std::string::npos) << r.output;
  // The camera of the last view, read the way the viewer reads the path.
  const std::string camera_file = (dir / "last.json").string();
  write_text(camera_file, camera_to_json(load_camera_path(path_file).at(4)));
  const RunResult rr = run_shell(sparseleap_exe().string() +
                                 " render --backend cpu --volume builtin:neurites:64x64x64 --size 320x240 --camera " +
                                 camera_file + " --out " + (dir / "render").string() + " 2>&1");
  ASSERT_EQ(rr.exit_code, 0) << rr.output;
  const Image want = read_png((dir / "render.png").string());
  const Image img = read_png(shot);
  ASSERT_EQ(want.width, kCanvasW);
  ASSERT_EQ(img.height, kCanvasH);
  const Canvas got{img};
  int differing = 0;
  for (int y = 0; y < kCanvasH; ++y)
    for (int x = 0; x < kCanvasW; ++x) differing += got.at(x, y) != want.at(x, y);
  EXPECT_EQ(differing, 0);
  EXPECT_GT(lit_fraction(got), 0.02);
}

TEST_F(ViewerWindow, ProgressiveOffRendersEveryFrameAtFullResolution) {
  const RunResult r = run_view("view " + kSmall + " --frames 4 --spin 10 --progressive off");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("view: 4 frames"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("pixels 1;"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("refined in"), std::string::npos) << r.output;
}

// `--lists gl` in the viewer: the OpenGL builder runs on the render worker's own headless context (a
// context is current on one thread) beside the window's, and the canvas is the CPU lists' image.
TEST_F(ViewerWindow, GlListsShowTheCpuListsImage) {
  const auto dir = scratch_dir();
  Image img[2];
  const char* lists[2] = {"cpu", "gl"};
  for (int i = 0; i < 2; ++i) {
    const std::string shot = (dir / (std::string(lists[i]) + ".png")).string();
    const RunResult r = run_view("view " + kSmall + " --lists " + lists[i] +
                                                       " --no-stats --frames 2 --screenshot " + shot);
    if (i == 1 && r.exit_code != 0 && r.output.find("--lists") != std::string::npos) {
      GTEST_SKIP() << "no GL list builder here: " << r.output;
    }
    ASSERT_EQ(r.exit_code, 0) << r.output;
    img[i] = read_png(shot);
  }
  ASSERT_EQ(img[0].width, img[1].width);
  ASSERT_EQ(img[0].height, img[1].height);
  const Canvas a{img[0]}, b{img[1]};
  int differing = 0;
  for (int y = 0; y < kCanvasH; ++y)
    for (int x = 0; x < kCanvasW; ++x) differing += a.at(x, y) != b.at(x, y);
  EXPECT_EQ(differing, 0);
  EXPECT_GT(lit_fraction(a), 0.02);
}

// No window is needed for these: bad input and a missing display are one line and a non-zero exit.
TEST(ViewerCli, NoDisplayIsOneClearLine) {
#ifndef SL_HAVE_VIEWER
  SL_SKIP_OR_FAIL("this build has no viewer");
#endif
  const RunResult r = run_with_display("", "view " + kSmall + " --frames 1");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  EXPECT_NE(r.output.find("sparseleap: error: view: cannot open a window"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("Xvfb"), std::string::npos) << r.output;
}

TEST(ViewerCli, BadOptionsFailBeforeAWindowOpens) {
  for (const std::string args : {"view --method warp", "view --mode sideways", "view --size 0x10",
                                 "view --view upside-down", "view --scale 2", "view --volume builtin:nope",
                                 "view --volume /no/such/file.nrrd", "view --mode labels --volume missing.nrrd",
                                 "view --frames -1", "view --progressive maybe", "view --frame-budget-ms 0",
                                 "view --path /no/such/path.json", "view --path p.json --spin 5",
                                 "view --volume builtin:neurites:16x16x16 --cache-mb 64 --method octree",
                                 "view --volume procedural:neurites:64x64x64 --mode labels",
                                 "view --volume builtin:neurites:16x16x16 --cache-mb 64 --lod-bias 0"}) {
    const RunResult r = run_with_display("", args);
    EXPECT_NE(r.exit_code, 0) << args;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << args << ": " << r.output;
    EXPECT_EQ(r.output.find("cannot open a window"), std::string::npos) << args << ": " << r.output;
  }
}

}  // namespace
}  // namespace sl::test
