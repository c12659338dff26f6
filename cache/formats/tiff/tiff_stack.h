// TIFF stacks for `ingest`: a directory of single-page 2-D TIFFs (one z-slice each, in name order) or
// one multipage TIFF (one page per slice), 8- or 16-bit unsigned grayscale (or 32-bit float), stripped
// or tiled, any compression libtiff decodes. Spacing is 1 (TIFF resolution tags describe print size,
// not voxel size). Read slice by slice through libtiff.
#pragma once

#include <memory>
#include <string>

#include "cache/formats/slab_reader.h"

namespace sl {

// Throws InputError(path, reason) for an empty directory, colour or unsupported sample formats, or
// slices whose size or type differ.
std::unique_ptr<SlabReader> open_tiff_stack(const std::string& path);

}  // namespace sl
