// Helpers for the OME-Zarr tests: the python3-zarr peer (tests/data_tools/zarr_tool.py, run with
// Debian's /usr/bin/python3, not whatever python3 is first on PATH) and raw expected files.
#pragma once

#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "tests/test_util.h"

namespace sl::test {

inline const char* kPeerPython = "/usr/bin/python3";

// True when /usr/bin/python3 can import the named modules ("zarr, numcodecs").
inline bool python_has(const std::string& modules) {
  const std::string cmd = std::string(kPeerPython) + " -c 'import " + modules + "' >/dev/null 2>&1";
  return std::system(cmd.c_str()) == 0;
}

// Runs zarr_tool.py with `args`; returns its exit code and fills `out` with stdout + stderr.
inline int run_peer(const std::string& args, std::string* out = nullptr) {
  const std::string cmd = std::string(kPeerPython) + " " + SL_SOURCE_DIR + "/tests/data_tools/zarr_tool.py " + args +
                          " 2>&1";
  const test::RunResult r = test::run_shell(cmd);
  if (out) *out = r.output;
  return r.exit_code;
}

// The Zarr v3 peer (tests/data_tools/zarr3_tool.py): zarr-python 3 in the virtual environment that
// scripts/setup makes, since Debian ships only zarr-python 2.
inline std::string peer3_python() { return std::string(SL_SOURCE_DIR) + "/.venv-peers/bin/python"; }

inline bool peer3_available() {
  const std::string cmd = peer3_python() + " -c 'import zarr, numcodecs, crc32c; assert int(zarr.__version__.split(\".\")[0]) >= 3'"
                          " >/dev/null 2>&1";
  return std::system(cmd.c_str()) == 0;
}

inline int run_peer3(const std::string& args, std::string* out = nullptr) {
  const std::string cmd = peer3_python() + " " + SL_SOURCE_DIR + "/tests/data_tools/zarr3_tool.py " + args + " 2>&1";
  const test::RunResult r = test::run_shell(cmd);
  if (out) *out = r.output;
  return r.exit_code;
}

inline std::vector<std::byte> read_bytes(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::vector<char> c((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  std::vector<std::byte> b(c.size());
  for (std::size_t i = 0; i < c.size(); ++i) b[i] = std::byte(c[i]);
  return b;
}

}  // namespace sl::test

// Skips (never silently passes; fails under CI) when the python3-zarr peer is missing.
#define SL_REQUIRE_PYTHON(modules)                                                                   \
  do {                                                                                               \
    if (!::sl::test::python_has(modules)) {                                                          \
      SL_SKIP_OR_FAIL("/usr/bin/python3 cannot import " + std::string(modules) +                     \
                      " (install python3-zarr python3-numcodecs python3-tifffile python3-nibabel)"); \
    }                                                                                                \
  } while (0)

// Skips (fails under CI) when the zarr-python 3 peer is missing.
#define SL_REQUIRE_PEER3()                                                                              \
  do {                                                                                                  \
    if (!::sl::test::peer3_available()) {                                                               \
      SL_SKIP_OR_FAIL(::sl::test::peer3_python() + " cannot import zarr>=3, numcodecs, crc32c (run scripts/setup)"); \
    }                                                                                                   \
  } while (0)
