// The tensorstore peer for the Neuroglancer precomputed and Zarr v3 tests
// (tests/data_tools/tensorstore_tool.py, run with the virtual environment scripts/setup makes,
// .venv-peers/bin/python).
#pragma once

#include <cstdlib>
#include <string>

#include "tests/cache/formats/zarr_test_util.h"
#include "tests/test_util.h"

namespace sl::test {

inline bool tensorstore_available() {
  const std::string cmd = peer3_python() + " -c 'import tensorstore, numpy' >/dev/null 2>&1";
  return std::system(cmd.c_str()) == 0;
}

// Runs tensorstore_tool.py with `args`; returns its exit code and fills `out` with stdout + stderr.
inline int run_tensorstore(const std::string& args, std::string* out = nullptr) {
  const test::RunResult r =
      test::run_shell(peer3_python() + " " + SL_SOURCE_DIR + "/tests/data_tools/tensorstore_tool.py " + args + " 2>&1");
  if (out) *out = r.output;
  return r.exit_code;
}

}  // namespace sl::test

// Skips (fails under CI) when the tensorstore peer is missing.
#define SL_REQUIRE_TENSORSTORE()                                                                    \
  do {                                                                                              \
    if (!::sl::test::tensorstore_available()) {                                                     \
      SL_SKIP_OR_FAIL(::sl::test::peer3_python() + " cannot import tensorstore (run scripts/setup)"); \
    }                                                                                               \
  } while (0)
