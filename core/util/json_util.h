// Small helpers for reading user JSON with errors that name the file and the offending key.
#pragma once

#include <nlohmann/json.hpp>
#include <cstdint>
#include <istream>
#include <stdexcept>
#include <string>

#include "core/util/math.h"

namespace sl {

// Largest JSON file read: it is parsed whole in memory (the DOM takes several times the text), and no
// transfer function, camera, path or Zarr metadata comes near it; bigger is refused before reading.
constexpr std::uintmax_t kMaxJsonBytes = std::uintmax_t(64) << 20;
// "is N MiB; JSON files are read ... at most 64 MiB" when `bytes` exceeds kMaxJsonBytes, else empty.
std::string json_too_large(std::uintmax_t bytes);
// Reads all of `in` into `out` unless it holds more than kMaxJsonBytes (a huge file, or a device such
// as /dev/zero, whose size no stat tells): then false, having read no more than kMaxJsonBytes + 1.
bool read_json_bytes(std::istream& in, std::string& out);

// Whole file as text; InputError(path, ...) when it cannot be read or exceeds kMaxJsonBytes.
std::string read_file_text(const std::string& path);
// nlohmann's message without its "[json.exception.type_error.302] " prefix.
std::string json_error_text(const nlohmann::json::exception& e);
// f(), where a member of an unexpected type (a number where a name belongs) that reaches one of
// nlohmann's typed reads is the input's fault: std::runtime_error("unexpected JSON type (...)"), which
// the caller names with its file like its other refusals.
template <class F>
auto json_typed(F&& f) -> decltype(f()) {
  try {
    return f();
  } catch (const nlohmann::json::exception& e) {
    throw std::runtime_error("unexpected JSON type (" + json_error_text(e) + ")");
  }
}
// Parses JSON; InputError(origin, "malformed JSON: ...") on syntax errors.
nlohmann::json parse_json(const std::string& text, const std::string& origin);
float json_number(const nlohmann::json& j, const char* key, const std::string& origin);
vec3 json_vec3(const nlohmann::json& j, const char* key, const std::string& origin, bool required);

}  // namespace sl
