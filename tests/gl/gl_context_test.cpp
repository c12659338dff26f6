// GL contexts: headless EGL reports its renderer; impossible requests and a missing display fail with
// a clear GlError; a GLFW window (under a private Xvfb when no display is set) gives the same builder
// results as the headless context — one code path for both ways of getting a context.
#include "gl/gl_context.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fcntl.h>

#include <cstdlib>
#include <optional>

#include "core/lists/segment_list_builder.h"
#include "gl/gl_segment_list_builder.h"
#include "tests/gl/gl_test_util.h"

extern char** environ;

// Mesa and the GL dispatch libraries keep process-lifetime allocations (driver screens, JIT caches,
// TLS). LeakSanitizer reports them when the suite runs under SL_SANITIZE; they are not ours.
extern "C" const char* __lsan_default_suppressions() {
  return "leak:libEGL_mesa\nleak:libGLX_mesa\nleak:swrast_dri\nleak:libgallium\nleak:libLLVM\nleak:libglapi\n"
         "leak:libEGL.so\nleak:libGL.so\nleak:libGLdispatch\nleak:libglfw\nleak:libX11\nleak:libepoxy\n"
         "leak:libdrm\nleak:libxcb\n";
}

namespace sl {
namespace {

// Restores an environment variable on scope exit.
class EnvOverride {
 public:
  EnvOverride(const char* name, const char* value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = old;
    if (value) {
      setenv(name, value, 1);
    } else {
      unsetenv(name);
    }
  }
  ~EnvOverride() {
    if (old_) {
      setenv(name_, old_->c_str(), 1);
    } else {
      unsetenv(name_);
    }
  }

 private:
  const char* name_;
  std::optional<std::string> old_;
};

// A private X server for the windowed test: `Xvfb -displayfd` picks a free display and writes its
// number to a pipe once it accepts connections. Stopped (by its pid) in the destructor.
class PrivateXvfb {
 public:
  PrivateXvfb() {
    int fds[2];
    if (pipe(fds) != 0) return;
    const std::string fd = std::to_string(fds[1]);
    const char* argv[] = {"Xvfb", "-displayfd", fd.c_str(), "-screen", "0", "320x240x24", "-nolisten", "tcp", nullptr};
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addclose(&actions, fds[0]);
    posix_spawn_file_actions_addopen(&actions, 2, "/dev/null", O_WRONLY, 0);  // quiet: warnings about fonts
    const int rc = posix_spawnp(&pid_, "Xvfb", &actions, nullptr, const_cast<char* const*>(argv), environ);
    posix_spawn_file_actions_destroy(&actions);
    close(fds[1]);
    if (rc != 0) {
      pid_ = -1;
      close(fds[0]);
      return;
    }
    std::string number;
    char c;
    while (read(fds[0], &c, 1) == 1 && c != '\n') number += c;
    close(fds[0]);
    if (!number.empty()) display_ = ":" + number;
  }
  ~PrivateXvfb() {
    if (pid_ > 0) {
      kill(pid_, SIGTERM);
      waitpid(pid_, nullptr, 0);
    }
  }
  const std::string& display() const { return display_; }

 private:
  pid_t pid_ = -1;
  std::string display_;
};

TEST(GlContext, HeadlessReportsRendererAndVersion) {
  SL_REQUIRE_GL(ctx);
  const GlInfo& i = ctx->info();
  std::printf("[ GL       ] %s (GLSL %s, vendor %s)\n", i.summary().c_str(), i.glsl_version.c_str(), i.vendor.c_str());
  EXPECT_GE(i.major * 10 + i.minor, 45);
  EXPECT_FALSE(i.renderer.empty());
  EXPECT_EQ(i.platform.rfind("egl", 0), 0u) << i.platform;
  EXPECT_EQ(ctx->window(), nullptr);
}

TEST(GlContext, ImpossibleVersionFailsWithAClearMessage) {
  SL_REQUIRE_GL(ctx);  // EGL works here; only the request is impossible
  GlContextOptions o;
  o.major = 9;
  o.minor = 9;
  try {
    GlContext::create_headless(o);
    FAIL() << "an OpenGL 9.9 context cannot exist";
  } catch (const GlError& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind("opengl: ", 0), 0u) << what;
    EXPECT_NE(what.find("9.9"), std::string::npos) << what;
  }
  {
    // create_any tries headless, then a hidden window; with no display both fail, each with its reason.
    EnvOverride display("DISPLAY", nullptr);
    EnvOverride wayland("WAYLAND_DISPLAY", nullptr);
    try {
      GlContext::create_any(o);
      FAIL() << "an OpenGL 9.9 context cannot exist";
    } catch (const GlError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("headless: EGL: cannot create an OpenGL 9.9 core context"), std::string::npos) << what;
      EXPECT_NE(what.find("windowed: GLFW"), std::string::npos) << what;
    }
  }
  ctx->make_current();  // the failed attempts must not disturb the working context
  SegmentListBuffer lists;
  EXPECT_NO_THROW(GlSegmentListBuilder(*ctx).build_segment_lists(OccupancyGeometry{}, {}, make_ray_generator(Camera{}, 4, 4), lists));
}

TEST(GlContext, WindowWithoutDisplayFailsWithAClearMessage) {
  EnvOverride display("DISPLAY", nullptr);
  EnvOverride wayland("WAYLAND_DISPLAY", nullptr);
  try {
    GlContext::create_window(64, 64, "sparseleap test", false);
    FAIL() << "a window cannot be made without a display";
  } catch (const GlError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("GLFW"), std::string::npos) << what;
    EXPECT_NE(what.find("DISPLAY"), std::string::npos) << what;
    std::printf("[ GL       ] %s\n", what.c_str());
  }
  if (GlContext* c = test::shared_gl_context()) c->make_current();
}

TEST(GlContext, WindowedContextBuildsTheSameListsAsTheCpu) {
  SL_REQUIRE_GL(headless);
  std::optional<PrivateXvfb> xvfb;  // declared before the window: the server outlives it
  std::optional<EnvOverride> display;
  if (!std::getenv("DISPLAY")) {
    xvfb.emplace();
    if (xvfb->display().empty()) SL_SKIP_OR_FAIL("no DISPLAY, and Xvfb could not be started");
    display.emplace("DISPLAY", xvfb->display().c_str());
  }
  {
    std::unique_ptr<GlContext> window = GlContext::create_window(64, 48, "sparseleap gl test", false);
    const GlInfo& i = window->info();
    std::printf("[ GL       ] windowed: %s\n", i.summary().c_str());
    EXPECT_EQ(i.platform, "glfw");
    EXPECT_NE(window->window(), nullptr);
    EXPECT_GE(i.major * 10 + i.minor, 45);
    const test::GlFixture f = test::random_gl_fixture(17, ivec3(45, 39, 51), vec3(1.0f), 4, 100);
    const RayGenerator gen =
        make_ray_generator(test::gl_perspective(vec3(80.0f, 60.0f, 90.0f), vec3(22.0f, 19.0f, 25.0f)), 61, 47);
    const auto order = build_visibility_order(f.tree, f.geometry, view_point(gen));
    SegmentListBuffer cpu, gl;
    build_segment_lists(f.geometry, order, gen, cpu);
    GlSegmentListBuilder builder(*window);
    builder.build_segment_lists(f.geometry, order, gen, gl);
    test::expect_same_lists(*window, gl, cpu);
  }
  headless->make_current();
}

}  // namespace
}  // namespace sl
