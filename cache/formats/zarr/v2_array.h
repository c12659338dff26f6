// Zarr v2 array metadata (an array's .zarray) read into and written from the reader's ArrayMeta
// (meta.h): shape and chunks, a little- or big-endian dtype, C order, no filters, the fill value, the
// dimension separator and the compressor (compressor.h). The v3 counterpart is v3_array.h.
#pragma once

#include <string>

#include <nlohmann/json_fwd.hpp>

#include "cache/formats/zarr/meta.h"

namespace sl::zarr::v2 {

// Parses one .zarray. Throws std::runtime_error with the reason (the caller names the store and array).
ArrayMeta parse_array(const nlohmann::json& j);

// The dtype string for a type, little-endian ("|u1", "<u2", "<u4", "<f4").
std::string dtype_string(VoxelType t);
// The .zarray of `m` (as the store writer writes it: little-endian, C order, no filters).
nlohmann::json to_json(const ArrayMeta& m);

}  // namespace sl::zarr::v2
