// Bench reports as tables of columns: every CSV column and JSON field is one entry, its name and how
// to read it from a row, so a CSV header and its rows, or a CSV column and the JSON field of the same
// figure, cannot drift apart.
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <ostream>
#include <variant>

namespace sl::app {

// One value of a report: the CSV prints it with operator<<, the JSON keeps its type (counts stay
// unsigned integers, times doubles).
using Cell = std::variant<const char*, int, std::uint64_t, double>;

// A CSV column (the name is its header) or a JSON field (the name is its key), read from a Row.
template <class Row>
struct Column {
  const char* name;
  Cell (*of)(const Row&);
  bool per_view = false;  // out-of-core frame columns that the view's JSON entry also holds
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
    std::visit([&](auto v) { csv << v; }, c.of(row));
    sep = ",";
  }
  csv << '\n';
}

// The fields of `row` in `j`; with `per_view_only`, those of the columns marked per_view.
template <class Columns, class Row>
void add_json_fields(nlohmann::json& j, const Columns& columns, const Row& row, bool per_view_only = false) {
  for (const auto& c : columns) {
    if (!per_view_only || c.per_view) std::visit([&](auto v) { j[c.name] = v; }, c.of(row));
  }
}

}  // namespace sl::app
