// Zarr v3 array metadata (an array's zarr.json) mapped onto the reader's ArrayMeta (meta.h), so
// that every level of a v3 store goes through the same ArrayReader, brick cutting and pyramid checks as
// a v2 store. The read grid of a sharded array is its inner chunks (sharding_indexed), so bricks fetch
// only the inner chunks they overlap. Groups and NGFF 0.5 attributes ("ome") are read by meta.cpp.
#pragma once

#include <nlohmann/json_fwd.hpp>

#include "cache/formats/zarr/meta.h"

namespace sl::zarr::v3 {

// Parses one array zarr.json (zarr_format 3, node_type "array"). Throws std::runtime_error with the
// reason (the caller names the store and array).
ArrayMeta parse_array(const nlohmann::json& j);

}  // namespace sl::zarr::v3
