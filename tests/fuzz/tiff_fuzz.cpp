// TIFF stacks (cache/formats/tiff/tiff_stack.cpp): the input is one (multipage) .tif, read whole.
#include "tests/fuzz/fuzz_util.h"

SL_FUZZ_TARGET(input) { sl::fuzz::read_volume_file(input, "in.tif"); }
