#!/usr/bin/env bash
# CMakeLists.txt's choice of CUDA architectures, configured in a scratch folder: without a GPU, AUTO
# is PTX for compute_75 only; `release` is SASS for sm_75..sm_90 plus PTX for compute_90; an explicit
# CMAKE_CUDA_ARCHITECTURES wins and is kept on a reconfigure; SL_CUDA_ARCHS=AUTO chooses again once it
# is removed. Usage: cuda_archs.sh SOURCE_DIR SCRATCH_DIR
set -euo pipefail
src=$1 dir=$2
rm -rf "$dir"
fail=0
expect() {  # what, expected archs, cmake arguments...
  local what=$1 want=$2 got
  got=$(cmake -S "$src" -B "$dir" -DSL_REQUIRE_ALL=OFF -DSL_BUILD_TESTS=OFF "${@:3}" 2>&1 |
        sed -n 's/^-- sparseleap: CUDA backend ON (nvcc [^,]*, archs \([^:]*\):.*/\1/p')
  if [ "$got" = "$want" ]; then
    echo "cuda_archs: $what: $got"
  else
    echo "cuda_archs: $what: got '$got', want '$want'" >&2
    fail=1
  fi
}
query="$(dirname "$(command -v nvcc || echo /usr/local/cuda/bin/nvcc)")/__nvcc_device_query"
if [ -x "$query" ] && "$query" >/dev/null 2>&1; then
  echo "cuda_archs: this machine has a GPU; AUTO's no-GPU choice is not checked here"
else
  expect "AUTO without a GPU" "75-virtual"
fi
expect "release" "75-real;80-real;86-real;89-real;90" -DSL_CUDA_ARCHS=release
expect "explicit list" "86-real" -DCMAKE_CUDA_ARCHITECTURES=86-real
expect "explicit list, reconfigured" "86-real"
if ! grep -q "^CMAKE_CUDA_ARCHITECTURES" "$dir/CMakeCache.txt"; then fail=1; fi
expect "back to release" "75-real;80-real;86-real;89-real;90" -UCMAKE_CUDA_ARCHITECTURES -DSL_CUDA_ARCHS=release
rm -rf "$dir"
exit $fail
