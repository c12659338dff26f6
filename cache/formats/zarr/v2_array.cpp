#include "cache/formats/zarr/v2_array.h"

#include <limits>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "core/util/checked.h"
#include "core/util/json_util.h"

namespace sl::zarr::v2 {
namespace {

using json = nlohmann::json;

VoxelType parse_dtype(const std::string& s, bool& big_endian) {
  if (s.size() != 3) throw std::runtime_error("unsupported dtype '" + s + "'");
  const char e = s[0];
  const std::string t = s.substr(1);
  if (e != '<' && e != '>' && e != '|') throw std::runtime_error("unsupported dtype '" + s + "'");
  big_endian = e == '>';
  if (t == "u1") return VoxelType::U8;
  if (e == '|') throw std::runtime_error("unsupported dtype '" + s + "'");
  if (t == "u2") return VoxelType::U16;
  if (t == "u4") return VoxelType::U32;
  if (t == "f4") return VoxelType::F32;
  throw std::runtime_error("unsupported dtype '" + s + "' (supported: |u1, <u2, >u2, <u4, >u4, <f4, >f4)");
}

std::vector<std::int64_t> int_list(const json& j, const char* key) {
  if (!j.contains(key) || !j[key].is_array() || j[key].empty()) {
    throw std::runtime_error(std::string("\"") + key + "\" must be a non-empty list of integers");
  }
  std::vector<std::int64_t> v;
  for (const json& e : j[key]) {
    if (!e.is_number_integer()) throw std::runtime_error(std::string("\"") + key + "\" must hold integers");
    v.push_back(e.get<std::int64_t>());
  }
  return v;
}

}  // namespace

namespace {

ArrayMeta parse_array_checked(const json& j) {
  if (!j.is_object()) throw std::runtime_error(".zarray is not a JSON object");
  if (!j.contains("zarr_format") || j["zarr_format"] != 2) {
    throw std::runtime_error("zarr_format must be 2 in a .zarray (Zarr v3 arrays keep their metadata in zarr.json)");
  }
  ArrayMeta m;
  m.shape = int_list(j, "shape");
  m.chunks = int_list(j, "chunks");
  if (m.shape.size() != m.chunks.size()) throw std::runtime_error("shape and chunks differ in length");
  if (m.ndim() < 3 || m.ndim() > 5) {
    throw std::runtime_error("array has " + std::to_string(m.ndim()) + " dimensions; expected 3 (z, y, x) or 4-5 "
                             "with singleton leading axes");
  }
  for (int i = 0; i < m.ndim(); ++i) {
    if (m.shape[std::size_t(i)] < 1 || m.shape[std::size_t(i)] > std::numeric_limits<std::int32_t>::max()) {
      throw std::runtime_error("shape entry " + std::to_string(m.shape[std::size_t(i)]) + " is out of range");
    }
    if (m.chunks[std::size_t(i)] < 1 || m.chunks[std::size_t(i)] > std::numeric_limits<std::int32_t>::max()) {
      throw std::runtime_error("chunks entry " + std::to_string(m.chunks[std::size_t(i)]) + " is out of range");
    }
    if (i < m.ndim() - 3 && m.shape[std::size_t(i)] != 1) {
      throw std::runtime_error("leading (t/c) axis " + std::to_string(i) + " has size " +
                               std::to_string(m.shape[std::size_t(i)]) + "; only size 1 is supported");
    }
  }
  if (!j.contains("dtype") || !j["dtype"].is_string()) {
    throw std::runtime_error("dtype must be a string (structured dtypes are not supported)");
  }
  m.type = parse_dtype(j["dtype"].get<std::string>(), m.big_endian);
  const std::uint64_t bytes =
      checked_product(std::span<const std::int64_t>(m.chunks), "decoded chunk bytes", std::uint64_t(voxel_size(m.type)));
  if (bytes > kMaxChunkBytes) {
    throw std::runtime_error("chunks of " + std::to_string(std::uint64_t(bytes)) + " bytes exceed the 1 GiB limit");
  }
  const std::string order = j.value("order", std::string("C"));
  if (order != "C") throw std::runtime_error("order '" + order + "' is not supported (only C order)");
  if (j.contains("filters") && !j["filters"].is_null() && !(j["filters"].is_array() && j["filters"].empty())) {
    throw std::runtime_error("filters are not supported");
  }
  const json& fv = j.contains("fill_value") ? j["fill_value"] : json();
  if (fv.is_number()) {
    m.fill = fv.get<double>();
  } else if (fv.is_string() && m.type == VoxelType::F32) {
    const std::string s = fv.get<std::string>();
    if (s == "NaN") m.fill = std::numeric_limits<double>::quiet_NaN();
    else if (s == "Infinity") m.fill = std::numeric_limits<double>::infinity();
    else if (s == "-Infinity") m.fill = -std::numeric_limits<double>::infinity();
    else throw std::runtime_error("fill_value '" + s + "' is not a number");
  } else if (!fv.is_null()) {
    throw std::runtime_error("fill_value must be a number or null");
  }
  const std::string sep = j.value("dimension_separator", std::string("."));
  if (sep != "." && sep != "/") throw std::runtime_error("dimension_separator must be '.' or '/'");
  m.separator = sep[0];
  m.compressor = parse_compressor(j.contains("compressor") ? j["compressor"] : json());
  return m;
}

}  // namespace

// The checks above read values of a type they test first, but a member of an unexpected type (a
// number where a name belongs) can still reach one of nlohmann's typed reads: json_typed makes it the
// metadata's fault like every other refusal here.
ArrayMeta parse_array(const json& j) { return json_typed([&] { return parse_array_checked(j); }); }

std::string dtype_string(VoxelType t) {
  switch (t) {
    case VoxelType::U8: return "|u1";
    case VoxelType::U16: return "<u2";
    case VoxelType::U32: return "<u4";
    case VoxelType::F32: return "<f4";
  }
  return "?";
}

json to_json(const ArrayMeta& m) {
  json j;
  j["zarr_format"] = 2;
  j["shape"] = m.shape;
  j["chunks"] = m.chunks;
  j["dtype"] = dtype_string(m.type);
  j["order"] = "C";
  j["fill_value"] = m.fill;
  j["filters"] = nullptr;
  j["compressor"] = to_json(m.compressor);
  j["dimension_separator"] = std::string(1, m.separator);
  return j;
}

}  // namespace sl::zarr::v2
