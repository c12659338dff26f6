// Bench reports as tables of columns: every CSV column and JSON field is one entry, its name and how
// to read it from a row, so a CSV header and its rows, or a CSV column and the JSON field of the same
// figure, cannot drift apart.
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <ostream>
#include <string_view>
#include <variant>

#include "core/frame/stats.h"

namespace sl::app {

// One value of a report: the CSV prints it with operator<<, the JSON keeps its type (counts stay
// unsigned integers, times doubles).
using Cell = std::variant<const char*, int, std::uint64_t, double>;

// Cache hit rate per frame: distinct bricks the rays used that were resident, over those plus the
// distinct bricks they missed.
inline double hit_rate(const Stats& st) {
  const double all = double(st.cache.hits) + double(st.cache.misses);
  return all > 0.0 ? double(st.cache.hits) / all : 1.0;
}

// A frame's figure: its name is the column's header in every CSV and the field's key in every JSON.
struct StatsColumn {
  const char* name;
  Cell (*of)(const Stats&);
};

// Every frame figure a bench report holds, once; the reports name the ones they show.
inline constexpr StatsColumn kStatsColumns[] = {
    {"total_ms", [](const Stats& s) -> Cell { return s.time_ms.total; }},
    {"metadata_ms", [](const Stats& s) -> Cell { return s.time_ms.metadata; }},
    {"tree_ms", [](const Stats& s) -> Cell { return s.time_ms.tree; }},
    {"geometry_ms", [](const Stats& s) -> Cell { return s.time_ms.geometry; }},
    {"order_ms", [](const Stats& s) -> Cell { return s.time_ms.order; }},
    {"lists_ms", [](const Stats& s) -> Cell { return s.time_ms.lists; }},
    {"raycast_ms", [](const Stats& s) -> Cell { return s.time_ms.raycast; }},
    {"samples", [](const Stats& s) -> Cell { return s.samples; }},
    {"useful_samples", [](const Stats& s) -> Cell { return s.useful_samples; }},
    {"depth_complexity_avg", [](const Stats& s) -> Cell { return s.depth_complexity_avg; }},
    {"depth_complexity_max", [](const Stats& s) -> Cell { return std::uint64_t(s.depth_complexity_max); }},
    {"boxes", [](const Stats& s) -> Cell { return s.boxes; }},
    {"events", [](const Stats& s) -> Cell { return s.events; }},
    {"occupancy_misses", [](const Stats& s) -> Cell { return s.occupancy_misses; }},
    {"tree_nodes", [](const Stats& s) -> Cell { return s.tree_nodes; }},
    {"tree_bytes", [](const Stats& s) -> Cell { return s.tree_bytes; }},
    {"loads", [](const Stats& s) -> Cell { return s.cache.loads; }},
    {"hits", [](const Stats& s) -> Cell { return s.cache.hits; }},
    {"misses", [](const Stats& s) -> Cell { return s.cache.misses; }},
    {"hit_rate", [](const Stats& s) -> Cell { return hit_rate(s); }},
    {"pending", [](const Stats& s) -> Cell { return s.cache.pending; }},
    {"resident_mb", [](const Stats& s) -> Cell { return s.cache.resident_mb; }},
    {"page_table_bytes", [](const Stats& s) -> Cell { return s.cache.page_table_bytes; }},
    {"completeness", [](const Stats& s) -> Cell { return s.cache.completeness; }},
    {"lod_coarsened", [](const Stats& s) -> Cell { return s.cache.lod_coarsened; }},
    {"bricks_missing", [](const Stats& s) -> Cell { return s.cache.bricks_missing; }},
    {"failed", [](const Stats& s) -> Cell { return s.cache.failed; }},
    {"bricks_retried", [](const Stats& s) -> Cell { return s.cache.bricks_retried; }},
    {"retries", [](const Stats& s) -> Cell { return s.cache.retries; }},
    {"recovered", [](const Stats& s) -> Cell { return s.cache.recovered; }},
    {"prefetched", [](const Stats& s) -> Cell { return s.cache.prefetched; }},
    {"prefetch_hits", [](const Stats& s) -> Cell { return s.cache.prefetch_hits; }},
    {"stall", [](const Stats& s) -> Cell { return s.cache.stall ? 1 : 0; }},
};

// A CSV column (the name is its header) or a JSON field (the name is its key), read from a Row:
// either by `of`, or, for a figure of kStatsColumns (made by Column::stat), from the row's `stats`.
template <class Row>
struct Column {
  const char* name;
  Cell (*of)(const Row&) = nullptr;
  bool per_view = false;  // out-of-core frame columns that the view's JSON entry also holds
  Cell (*of_stats)(const Stats&) = nullptr;

  // The figure of kStatsColumns called `figure`; a name not there does not compile.
  static consteval Column stat(std::string_view figure, bool per_view = false) {
    for (const StatsColumn& c : kStatsColumns) {
      if (figure == c.name) return Column{c.name, nullptr, per_view, c.of};
    }
    throw "bench: no such stats column";
  }

  // The member `M` of the row.
  template <auto M>
  static constexpr Column field(const char* name) {
    return Column{name, [](const Row& row) -> Cell { return row.*M; }};
  }

  Cell operator()(const Row& row) const {
    if constexpr (requires { row.stats; }) {
      if (of_stats) return of_stats(row.stats);
    }
    return of(row);
  }
};

template <class Columns>
void write_csv_header(std::ostream& csv, const Columns& columns) {
  const char* sep = "";
  for (const auto& c : columns) {
    csv << sep << c.name;
    sep = ",";
  }
  csv << '\n';
}

template <class Columns, class Row>
void write_csv_row(std::ostream& csv, const Columns& columns, const Row& row) {
  const char* sep = "";
  for (const auto& c : columns) {
    csv << sep;
    std::visit([&](auto v) { csv << v; }, c(row));
    sep = ",";
  }
  csv << '\n';
}

// The fields of `row` in `j`; with `per_view_only`, those of the columns marked per_view.
template <class Columns, class Row>
void add_json_fields(nlohmann::json& j, const Columns& columns, const Row& row, bool per_view_only = false) {
  for (const auto& c : columns) {
    if (!per_view_only || c.per_view) std::visit([&](auto v) { j[c.name] = v; }, c(row));
  }
}

}  // namespace sl::app
