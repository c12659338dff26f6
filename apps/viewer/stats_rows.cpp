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

// One line per field: the overlay shows what core/frame/stats.h counts (STYLE.md #10).
void add_rows(std::vector<StatRow>& r, const Stats& s) {
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
  r.push_back({"tree KB", ms(double(s.tree_bytes) / 1024.0)});
  r.push_back({"depth cx", fmt("%.0f", double(s.depth_complexity_min)) + "/" + fmt("%.2f", s.depth_complexity_avg) +
                               "/" + fmt("%.0f", double(s.depth_complexity_max))});
  r.push_back({"occ. misses", human_count(double(s.occupancy_misses))});
  r.push_back({"overflows", human_count(double(s.list_overflows))});
  // Out-of-core cache (DESIGN.md "Virtual memory"): only frames of the out-of-core path carry it.
  if (s.cache.present) {
    const CacheStats& c = s.cache;
    r.push_back({"cache", "", true});
    r.push_back({"resident MB", ms(c.resident_mb)});
    r.push_back({"page table KB", ms(double(c.page_table_bytes) / 1024.0)});
    r.push_back({"hits", human_count(double(c.hits))});
    r.push_back({"misses", human_count(double(c.misses))});
    r.push_back({"loads", human_count(double(c.loads))});
    r.push_back({"pending", human_count(double(c.pending))});
    r.push_back({"evictions", human_count(double(c.evictions))});
    r.push_back({"failed", human_count(double(c.failed))});
    r.push_back({"bricks retried", human_count(double(c.bricks_retried))});
    r.push_back({"retries", human_count(double(c.retries))});
    r.push_back({"recovered", human_count(double(c.recovered))});
    r.push_back({"converged at", c.converged_at_frame < 0 ? "-" : std::to_string(c.converged_at_frame)});
    r.push_back({"complete", fmt("%.3f", c.completeness) +
                                 (c.lod_coarsened > 0.0 ? fmt(" (%.0f%% coarser)", 100.0 * c.lod_coarsened) : "")});
    r.push_back({"bricks missing", human_count(double(c.bricks_missing))});
  }
}

}  // namespace

std::vector<StatRow> stats_rows(const Stats& s) {
  std::vector<StatRow> rows;
  add_rows(rows, s);
  return rows;
}

std::uint64_t pending_loads(const Stats& s) { return s.cache.present ? s.cache.pending : 0; }

// The renderer's own verdict (converged: nothing in flight and nothing left to resolve), not the miss
// count: a settled view whose bricks do not fit keeps misses (and completeness < 1) that another frame
// will not change, and repeating it would render the same image forever.
bool still_refining(const Stats& s) { return s.cache.present && s.cache.converged_at_frame < 0; }

std::string human_count(double n) {
  if (!std::isfinite(n)) return "-";
  const double a = std::fabs(n);
  if (a >= 1e9) return fmt("%.2f G", n / 1e9);
  if (a >= 1e6) return fmt("%.2f M", n / 1e6);
  if (a >= 1e4) return fmt("%.1f k", n / 1e3);
  return fmt("%.0f", n);
}

}  // namespace sl::viewer
