// NIfTI (cache/formats/nifti/nifti.cpp): the input is the .nii file (zlib's gzopen reads plain and gzip
// files alike, so .nii.gz inputs are just gzip-compressed ones), read whole as render does.
#include "tests/fuzz/fuzz_util.h"

SL_FUZZ_TARGET(input) { sl::fuzz::read_volume_file(input, "in.nii"); }
