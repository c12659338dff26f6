// The viewer's stats overlay as data: label/value rows made from one frame's Stats (STYLE.md #10:
// one struct, printed by every front end). Adding a field to the overlay is one line in
// stats_rows.cpp; the out-of-core cache rows appear for frames that carry cache counters.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/frame/stats.h"

namespace sl::viewer {

struct StatRow {
  std::string label;
  std::string value;
  bool heading = false;  // a group title ("time ms", "cache"), drawn without a value
};

std::vector<StatRow> stats_rows(const Stats& s);

// Bricks still being loaded after this frame (0 in core): the overlay's loading indicator.
std::uint64_t pending_loads(const Stats& s);
// Whether another frame of the same view would show more (out of core: the renderer has not converged
// — loads pending or misses still to resolve): the viewer then keeps rendering, so the image refines
// as data stream in (DESIGN.md "Virtual memory"). A converged frame stops it even when incomplete (the
// bricks that do not fit at a pinned level stay missing whatever is rendered next).
bool still_refining(const Stats& s);

// "12.3 M", "4.5 k", "17": counts people read at a glance.
std::string human_count(double n);

}  // namespace sl::viewer
