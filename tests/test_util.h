// Helpers shared by the test suites: scratch directories, running the sparseleap executable, and
// skipping a test that cannot run here (or failing it, under CI).
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <string>

#include "core/util/image.h"

namespace sl::test {

// Largest difference of any RGBA component between two images of the same size.
inline float max_abs_diff(const Image& a, const Image& b) {
  float m = 0.0f;
  for (std::size_t i = 0; i < a.rgba.size(); ++i) {
    const vec4 d = glm::abs(a.rgba[i] - b.rgba[i]);
    m = std::max({m, d.x, d.y, d.z, d.w});
  }
  return m;
}

// True under CI (CI=true) or with SL_REQUIRE_ALL=1: then every suite must run in full, and a test
// that cannot run here fails instead of skipping (STYLE.md #14).
bool require_all();

// A fresh, empty directory under the build tree, named for the current test.
std::filesystem::path scratch_dir();

// Path of the built `sparseleap` executable.
std::filesystem::path sparseleap_exe();

struct RunResult {
  int exit_code = -1;
  std::string output;  // stdout and stderr, interleaved
};
// Runs a shell command line and captures its standard output (add "2>&1" for stderr too).
RunResult run_shell(const std::string& line);
// Runs `sparseleap <args>` through the shell and captures its output.
RunResult run_sparseleap(const std::string& args);

std::string read_text(const std::filesystem::path& p);
void write_text(const std::filesystem::path& p, const std::string& text);

}  // namespace sl::test

// Ends the calling test because this machine lacks a part it needs, saying which (`reason`, a
// std::string): a skip on a developer's machine, a failure under CI=true or SL_REQUIRE_ALL=1, so a CI
// machine missing a package cannot pass without running the suite.
#define SL_SKIP_OR_FAIL(reason)                                                                  \
  do {                                                                                           \
    const std::string sl_skip_reason_ = (reason);                                                \
    if (::sl::test::require_all()) {                                                             \
      GTEST_FAIL() << sl_skip_reason_ << " (CI=true or SL_REQUIRE_ALL=1: this test must run here)"; \
    }                                                                                            \
    GTEST_SKIP() << sl_skip_reason_;                                                             \
  } while (0)
