// Small helpers for reading user JSON with errors that name the file and the offending key.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "core/math.h"

namespace sl {

// Whole file as text; InputError(path, ...) when it cannot be read.
std::string read_file_text(const std::string& path);
// Parses JSON; InputError(origin, "malformed JSON: ...") on syntax errors.
nlohmann::json parse_json(const std::string& text, const std::string& origin);
float json_number(const nlohmann::json& j, const char* key, const std::string& origin);
vec3 json_vec3(const nlohmann::json& j, const char* key, const std::string& origin, bool required);

}  // namespace sl
