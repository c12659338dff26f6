#include "apps/viewer/stats_rows.h"

#include <cmath>
#include <cstdio>

namespace sl::viewer {

namespace {

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

std::string ms(double v) { return fmt("%.1f", v); }

// A row for a Stats member that may not exist yet (the out-of-core cache adds its fields): the
// requires-expression is checked where S is a template parameter, so a missing member drops the row
// instead of breaking the build. Several spellings are listed where the cache's naming is not settled.
#define SL_OPTIONAL_ROW(rows, s, field, label, to_text)                          \
  if constexpr (requires { s.field; }) {                                        \
    rows.push_back({label, to_text(double(s.field))});                          \
  }

template <class S>
void add_rows(std::vector<StatRow>& r, const S& s) {
  r.push_back({"frame ms", ms(s.time_ms.total)});
  r.push_back({"size", std::to_string(s.width) + "x" + std::to_string(s.height)});
  r.push_back({s.backend + " " + s.method + " " + s.mode, "", true});
  r.push_back({"metadata", ms(s.time_ms.metadata)});
  r.push_back({"tree", ms(s.time_ms.tree)});
  r.push_back({"geometry", ms(s.time_ms.geometry)});
  r.push_back({"order", ms(s.time_ms.order)});
  r.push_back({"lists", ms(s.time_ms.lists)});
  r.push_back({"raycast", ms(s.time_ms.raycast)});
  r.push_back({"work", "", true});
  r.push_back({"samples", human_count(double(s.samples))});
  r.push_back({"useful", human_count(double(s.useful_samples))});
  r.push_back({"rays", human_count(double(s.rays))});
  r.push_back({"boxes", human_count(double(s.boxes))});
  r.push_back({"events", human_count(double(s.events))});
  r.push_back({"tree nodes", human_count(double(s.tree_nodes))});
  r.push_back({"depth cx", fmt("%.0f", double(s.depth_complexity_min)) + "/" + fmt("%.2f", s.depth_complexity_avg) +
                               "/" + fmt("%.0f", double(s.depth_complexity_max))});
  r.push_back({"occ. misses", human_count(double(s.occupancy_misses))});
  r.push_back({"overflows", human_count(double(s.list_overflows))});
  // Out-of-core cache (DESIGN.md §4), shown once core/stats.h carries these fields.
  const std::size_t before = r.size();
  SL_OPTIONAL_ROW(r, s, resident_mb, "resident MB", ms)
  SL_OPTIONAL_ROW(r, s, cache_resident_mb, "resident MB", ms)
  SL_OPTIONAL_ROW(r, s, resident_bricks, "resident bricks", human_count)
  SL_OPTIONAL_ROW(r, s, pending_loads, "pending loads", human_count)
  SL_OPTIONAL_ROW(r, s, brick_misses, "brick misses", human_count)
  SL_OPTIONAL_ROW(r, s, cache_misses, "brick misses", human_count)
  SL_OPTIONAL_ROW(r, s, brick_loads, "bricks loaded", human_count)
  SL_OPTIONAL_ROW(r, s, bricks_loaded, "bricks loaded", human_count)
  SL_OPTIONAL_ROW(r, s, evictions, "evictions", human_count)
  if (r.size() > before) r.insert(r.begin() + std::ptrdiff_t(before), StatRow{"cache", "", true});
}

template <class S>
std::uint64_t pending_of(const S& s) {
  if constexpr (requires { s.pending_loads; }) {
    return std::uint64_t(s.pending_loads);
  } else {
    return 0;
  }
}

}  // namespace

std::vector<StatRow> stats_rows(const Stats& s) {
  std::vector<StatRow> rows;
  add_rows(rows, s);
  return rows;
}

std::uint64_t pending_loads(const Stats& s) { return pending_of(s); }

std::string human_count(double n) {
  if (!std::isfinite(n)) return "-";
  const double a = std::fabs(n);
  if (a >= 1e9) return fmt("%.2f G", n / 1e9);
  if (a >= 1e6) return fmt("%.2f M", n / 1e6);
  if (a >= 1e4) return fmt("%.1f k", n / 1e3);
  return fmt("%.0f", n);
}

}  // namespace sl::viewer
