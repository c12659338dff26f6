// NIfTI volumes through Debian's libnifti2 (the NIfTI reference library): NIfTI-1 and NIfTI-2, single
// files (.nii, .nii.gz) and .hdr/.img pairs (either name given; the pair may be gzip-compressed),
// either byte order. dim[1..3] are x, y, z (further dims must be 1), |pixdim[1..3]| the spacing
// (non-positive or non-finite values read as 1). Data types uint8, uint16, uint32, float32, and int8
// and int16, which become float32 (values kept exactly; sparseleap has no signed type). When
// scl_slope/scl_inter are not the identity (slope 0 or non-finite means unscaled, as the standard and
// nibabel use it), the values slope * v + inter are stored, as float32. libnifti reads non-finite
// float voxels as 0. Every problem is one InputError naming the file; libnifti's own diagnostics on
// stderr are silenced.
#pragma once

#include <memory>
#include <string>

#include "cache/formats/slab_reader.h"

namespace sl {

std::unique_ptr<SlabReader> open_nifti(const std::string& path);

// True for the names open_nifti reads (any case): .nii, .nii.gz, .hdr, .hdr.gz, .img, .img.gz.
bool is_nifti_path(const std::string& path);

// What `info` shows of a NIfTI file besides dims, type and spacing.
struct NiftiInfo {
  std::string format;       // "NIfTI-1, single file", "NIfTI-2, .hdr/.img pair", ...
  std::string scaling;      // "none", or "slope 2 inter -5 (stored as float32)"
  std::string orientation;  // axis directions of increasing x, y, z: "RAS (sform: MNI 152)"; "unknown (no qform or sform)"
};
NiftiInfo nifti_info(const std::string& path);

}  // namespace sl
