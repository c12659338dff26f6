#!/usr/bin/env bash
# The README's first command builds only the program: every command Ninja would run to make the
# targets `scripts/build` makes by default, in this build folder, compiles or links nothing of the
# test suites. A control asks the same of core_tests, whose commands must name tests/, so the check
# itself can fail. Usage: first_command_scope.sh SOURCE_DIR BUILD_DIR
set -euo pipefail
src=$1 build=$2
if [ ! -f "$build/build.ninja" ]; then
  echo "first_command_scope: $build was not configured with Ninja (scripts/build uses it): cannot list its commands" >&2
  exit 1
fi
targets=$(bash "$src/scripts/build" --print-targets)
# shellcheck disable=SC2086  # a list of targets
commands=$(ninja -C "$build" -t commands $targets)
if [ -z "$commands" ]; then
  echo "first_command_scope: no commands for '$targets'" >&2
  exit 1
fi
tests_pattern="$src/tests/|tests/CMakeFiles/"
control=$(ninja -C "$build" -t commands core_tests)
if ! grep -Eq "$tests_pattern" <<<"$control"; then
  echo "first_command_scope: control failed: core_tests' commands do not match '$tests_pattern'" >&2
  exit 1
fi
if grep -E "$tests_pattern" <<<"$commands" | head -5 | grep .; then
  echo "first_command_scope: the default build ($targets) compiles test code (the lines above)" >&2
  exit 1
fi
echo "first_command_scope: '$targets': $(wc -l <<<"$commands") commands, none from tests/"
