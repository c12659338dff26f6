// Helpers shared by the test suites: scratch directories and running the sparseleap executable.
#pragma once

#include <filesystem>
#include <string>

namespace sl::test {

// A fresh, empty directory under the build tree, named for the current test.
std::filesystem::path scratch_dir();

// Path of the built `sparseleap` executable.
std::filesystem::path sparseleap_exe();

struct RunResult {
  int exit_code = -1;
  std::string output;  // stdout and stderr, interleaved
};
// Runs `sparseleap <args>` through the shell and captures its output.
RunResult run_sparseleap(const std::string& args);

std::string read_text(const std::filesystem::path& p);
void write_text(const std::filesystem::path& p, const std::string& text);

}  // namespace sl::test
