// A volume file read whole into memory, whatever its format: NRRD (nrrd.h), NIfTI-1 (.nii, .nii.gz) or a
// TIFF stack (one multipage file or a directory of slices), the latter two through their slab readers
// (slab_reader.h) — the same readers `ingest` streams. Used by render, bench, view and info.
#pragma once

#include <string>

#include "core/scene/volume.h"

namespace sl {

// True for the names open_slab_reader() takes that are not NRRD (.nii, .nii.gz, .tif, .tiff, a directory).
bool is_slab_volume_path(const std::string& path);

// The file's dims, type and spacing (a header read; a TIFF directory lists its slices). InputError.
VolumeDesc read_volume_file_desc(const std::string& path);

// The whole volume. InputError(path, reason) for anything bad or short.
Volume read_volume_file(const std::string& path);

}  // namespace sl
