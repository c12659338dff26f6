#!/usr/bin/env bash
# The byte stores sit below the formats (cache/CMakeLists.txt): every project header a file of
# cache/stores/ includes is from cache/stores/ or core/, so where bytes live never depends on what they
# mean (sl_stores links sl_core only). A control asks the same of cache/formats/, which includes the
# stores, so the check itself can fail. Usage: stores_below_formats.sh SOURCE_DIR
set -euo pipefail
src=$1
outside() { grep -Hn '^#include "' "$@" | grep -Ev '#include "(cache/stores|core)/' || true; }
mapfile -t stores < <(find "$src/cache/stores" -name '*.h' -o -name '*.cpp')
mapfile -t formats < <(find "$src/cache/formats" -name '*.h' -o -name '*.cpp')
if [ "${#stores[@]}" -eq 0 ] || [ -z "$(outside "${formats[@]}")" ]; then
  echo "stores_below_formats: control failed: no stores, or cache/formats/ includes nothing outside stores and core" >&2
  exit 1
fi
if bad=$(outside "${stores[@]}") && [ -n "$bad" ]; then
  echo "$bad"
  echo "stores_below_formats: cache/stores/ includes the headers above (only cache/stores/ and core/ allowed)" >&2
  exit 1
fi
echo "stores_below_formats: ${#stores[@]} files of cache/stores/ include only cache/stores/ and core/"
