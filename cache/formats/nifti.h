// NIfTI-1 single-file volumes (.nii, or gzip-compressed .nii.gz) for `ingest`: the 348-byte header
// (either byte order, detected from sizeof_hdr), dim[1..3] as x, y, z (further dims must be 1),
// pixdim[1..3] as spacing (non-positive values read as 1), data from vox_offset. Data types uint8,
// uint16, uint32, float32, and int16, which is converted to float32 (values kept exactly; sparseleap
// has no signed type). Stored values are used as they are: scl_slope/scl_inter are not applied.
// NIfTI-2 and .hdr/.img pairs are refused with a clear message.
#pragma once

#include <memory>
#include <string>

#include "cache/formats/slab_reader.h"

namespace sl {

std::unique_ptr<SlabReader> open_nifti(const std::string& path);

}  // namespace sl
