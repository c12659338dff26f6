// Occupancy classes of the occupancy histogram tree (paper §5.1, DESIGN.md "Occupancy histogram tree").
#pragma once

#include <cstdint>

#include "core/util/config.h"

namespace sl {

// Empty/NonEmpty/Unknown are the three classes of the paper; Invalid is the "parent class" of the root
// (Alg. 2: "defined as not equal to any other class") and the class of a ray's final EXIT event.
enum class OccupancyClass : std::uint8_t { Empty = 0, NonEmpty = 1, Unknown = 2, Invalid = 3 };

inline constexpr int kOccupancyClassCount = 3;  // classes counted in an occupancy histogram

// Classes a ray must sample (Alg. 6: non-empty and unknown segments are sampled).
SL_HOST_DEVICE inline constexpr bool needs_sampling(OccupancyClass c) {
  return c == OccupancyClass::NonEmpty || c == OccupancyClass::Unknown;
}

inline const char* to_string(OccupancyClass c) {
  switch (c) {
    case OccupancyClass::Empty: return "empty";
    case OccupancyClass::NonEmpty: return "non-empty";
    case OccupancyClass::Unknown: return "unknown";
    default: return "invalid";
  }
}

}  // namespace sl
