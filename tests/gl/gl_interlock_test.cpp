// The interlock path's shaders (interlock.frag + the GLSL add_event) on llvmpipe. llvmpipe lacks
// GL_ARB_fragment_shader_interlock, but Mesa can be told to advertise it
// (MESA_EXTENSION_OVERRIDE, read once per process, before the first context), and llvmpipe's
// rasterizer shades each screen tile on one thread in primitive order, so per-pixel order holds even
// though begin/endInvocationInterlockARB do nothing there. This compiles and runs the interlock program
// and checks its lists against the CPU builder's. It does not prove the critical section on real
// hardware (that needs a GPU with the extension). The test re-runs this binary as a child process
// with the override set, since the suite's own context exists already.
#include <gtest/gtest.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <string>
#include <vector>

#include "core/lists/segment_list_builder.h"
#include "gl/gl_segment_list_builder.h"
#include "tests/gl/gl_test_util.h"

extern char** environ;

namespace sl {
namespace {

constexpr const char* kChildVar = "SL_GL_INTERLOCK_CHILD";

// The interlock program against the CPU builder, on a context that has the extension (its own, or
// llvmpipe's forced one in the child).
void check_interlock_program() {
  SL_REQUIRE_GL(ctx);
  ASSERT_TRUE(ctx->info().interlock()) << "MESA_EXTENSION_OVERRIDE did not take: " << ctx->info().summary();
  GlBuilderOptions o;
  o.path = GlBuilderOptions::Path::Interlock;
  GlSegmentListBuilder b(*ctx, o);
  ASSERT_EQ(b.path(), GlListPath::Interlock);
  const test::GlFixture f = test::random_gl_fixture(11, ivec3(61, 64, 45), vec3(1.0f, 0.5f, 2.0f), 4, 300);
  const Camera cams[] = {test::gl_perspective(vec3(100.0f, 70.0f, 150.0f), vec3(30.0f, 16.0f, 45.0f)),
                         test::gl_perspective(vec3(20.0f, 15.0f, 40.0f), vec3(50.0f, 16.0f, 10.0f), 90.0f),
                         test::gl_orthographic(vec3(100.0f, -50.0f, 80.0f), vec3(30.0f, 16.0f, 45.0f), 110.0f)};
  for (const Camera& cam : cams) {
    for (const float eps : {0.0f, 0.5f}) {
      const RayGenerator gen = make_ray_generator(cam, 61, 47);
      const auto order = build_visibility_order(f.tree, f.geometry, view_point(gen));
      SegmentListBuffer cpu, gl;
      const std::uint32_t capacity = eps > 0.0f ? kMaxEvents : 5u;  // also the overflow rule
      build_segment_lists_reference(f.geometry, order, gen, cpu, eps, capacity);
      GlBuildStats st = b.build(f.geometry, order, gen, capacity, eps);
      b.read_back(gl, &st);
      EXPECT_EQ(st.path, GlListPath::Interlock);
      test::expect_same_lists(*ctx, gl, cpu);
    }
  }
}

TEST(GlInterlock, InterlockProgramMatchesCpuOnLlvmpipeWithForcedExtension) {
  if (std::getenv(kChildVar)) {
    check_interlock_program();
    return;
  }
  SL_REQUIRE_GL(ctx);
  if (ctx->info().interlock()) {
    // A GPU with the extension: nothing to force, the program runs on this context as it is.
    check_interlock_program();
    return;
  }
  if (ctx->info().renderer.find("llvmpipe") == std::string::npos) {
    SL_SKIP_OR_FAIL("no interlock on " + ctx->info().renderer +
                    ", and forcing the extension is only meaningful on llvmpipe");
  }
  const std::string filter = "--gtest_filter=GlInterlock.InterlockProgramMatchesCpuOnLlvmpipeWithForcedExtension";
  std::vector<std::string> env_strings = {std::string(kChildVar) + "=1",
                                          "MESA_EXTENSION_OVERRIDE=+GL_ARB_fragment_shader_interlock"};
  for (char** e = environ; *e; ++e) {
    if (std::string(*e).rfind("MESA_EXTENSION_OVERRIDE=", 0) != 0) env_strings.emplace_back(*e);
  }
  std::vector<char*> envp;
  for (std::string& s : env_strings) envp.push_back(s.data());
  envp.push_back(nullptr);
  std::string self = "/proc/self/exe";
  char* argv[] = {self.data(), const_cast<char*>(filter.c_str()), nullptr};
  pid_t pid = -1;
  ASSERT_EQ(posix_spawn(&pid, "/proc/self/exe", nullptr, nullptr, argv, envp.data()), 0);
  int status = 0;
  ASSERT_EQ(waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status)) << "child crashed";
  EXPECT_EQ(WEXITSTATUS(status), 0) << "the interlock child failed (its output is above)";
}

}  // namespace
}  // namespace sl
