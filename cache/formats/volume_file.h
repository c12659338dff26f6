// A volume file, whatever its format, chosen by name: NRRD (nrrd/nrrd.h), NIfTI (nifti/nifti.h) or a TIFF
// stack (tiff/tiff_stack.h: one multipage file or a directory of slices). Streamed through its slab
// reader (slab_reader.h) by `ingest`, or read whole into memory (NRRD by its own whole-file reader) by
// render, bench, view and info.
#pragma once

#include <memory>
#include <string>

#include "cache/formats/slab_reader.h"
#include "core/scene/volume.h"

namespace sl {

// Chooses the reader by name: .nrrd/.nhdr (raw or gzip), .tif/.tiff (one multipage file) or a
// directory of .tif/.tiff files (one slice each, sorted by name), .nii/.nii.gz. Throws InputError.
std::unique_ptr<SlabReader> open_slab_reader(const std::string& path);

// True for the names open_slab_reader() takes that are not NRRD (.nii, .nii.gz, .tif, .tiff, a directory).
bool is_slab_volume_path(const std::string& path);

// The file's dims, type and spacing (a header read; a TIFF directory lists its slices). InputError.
VolumeDesc read_volume_file_desc(const std::string& path);

// The whole volume. InputError(path, reason) for anything bad or short.
Volume read_volume_file(const std::string& path);

}  // namespace sl
