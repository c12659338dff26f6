// Deterministic synthetic volumes for `sparseleap gen` and the built-in data set of `render`/`bench`
// (DESIGN.md "Programs"). Output depends only on (kind, dims, seed): never on the thread count or platform
// (own RNG and fixed per-voxel evaluation order; no std:: distributions, whose output is unspecified).
// Coordinates follow DESIGN.md "Ray casting": voxel i's centre is at i + 0.5, the volume box is [0, dims].
#pragma once

#include <cstdint>
#include <string>

#include "core/scene/volume.h"

namespace sl {

struct GeneratedVolume {
  Volume intensity;
  Volume labels;  // aligned segmentation; labels.empty() when the kind has none
  std::uint32_t label_count = 0;  // labels take values 0 (background) .. label_count
};

// kind:
//  - "neurites": stand-in for segmented EM data. Thin tubes (radius 1-4 voxels) along smooth random
//    paths, some crossing the whole volume, some branching; about 2 % of voxels non-zero, the number
//    of tubes growing with the volume. Intensity u8: per-tube brightness (120-255) times a smooth
//    profile falling from 1 to 0 across 1.5 voxels around the tube surface (half brightness on it),
//    so trilinear sampling sees smooth surfaces. Labels u16: the neurite id (a tube and its branches)
//    wherever the voxel centre lies inside the tube (distance <= radius); where tubes overlap, the
//    one whose surface is farthest outside wins. A voxel with intensity >= 128 is always labelled.
//  - "blobs": dense sum of truncated Gaussians, about 30 % of voxels non-zero, intensity u8 (1.0 of
//    summed amplitude = 255); labels u16 = 1 + index of the dominant Gaussian where its own value
//    exceeds 0.1 (of full scale), else 0.
//  - "organs": a few large segments filling most of the volume (like the paper's King Snake): a
//    superellipsoid body, about 74 % of the voxels, labelled skin (1), body (2), spine (3) and heart
//    (4, under 1 %); intensity u8 per label with a smooth pattern; labels u16.
//  - "sphere": f32, the distance of the voxel centre from the volume centre (dims / 2) in voxels, so
//    the isosurface at value r is a sphere of radius r. No labels.
// Throws InputError("gen", ...) for an unknown kind or invalid dims (validate_desc).
GeneratedVolume generate_volume(const std::string& kind, ivec3 dims, std::uint32_t seed = 1);

// Whether `kind` comes with labels; InputError("gen", ...) for an unknown kind.
bool generated_kind_has_labels(const std::string& kind);
// The bytes generate_volume(kind, dims) holds (intensity and labels), computed without generating,
// so callers can refuse what does not fit in memory first; InputError("gen", ...) for an unknown
// kind or non-positive dims.
std::uint64_t generated_bytes(const std::string& kind, ivec3 dims);

}  // namespace sl
