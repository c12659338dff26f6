// The viewer's stats overlay as data: label/value rows made from one frame's Stats (STYLE.md #10:
// one struct, printed by every front end). Adding a field to the overlay is one line in
// stats_rows.cpp; cache fields (resident MB, pending loads, misses, loads) appear by themselves once
// core/stats.h has them, through a compile-time presence check, so the viewer builds before and after.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/stats.h"

namespace sl::viewer {

struct StatRow {
  std::string label;
  std::string value;
  bool heading = false;  // a group title ("time ms", "cache"), drawn without a value
};

std::vector<StatRow> stats_rows(const Stats& s);

// Bricks still being loaded after this frame (0 when Stats has no such field yet): while non-zero
// the viewer keeps rendering so the image refines as data streams in (DESIGN.md §4).
std::uint64_t pending_loads(const Stats& s);

// "12.3 M", "4.5 k", "17": counts people read at a glance.
std::string human_count(double n);

}  // namespace sl::viewer
