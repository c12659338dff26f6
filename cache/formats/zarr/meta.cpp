#include "cache/formats/zarr/meta.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <limits>
#include <nlohmann/json.hpp>

#include "cache/formats/zarr/v2_array.h"
#include "cache/formats/zarr/v3_array.h"
#include "cache/formats/zarr/v3_codec.h"
#include "cache/stores/store_key.h"
#include "cache/stores/store_url.h"
#include "core/util/checked.h"
#include "core/util/config.h"
#include "core/util/error.h"
#include "core/util/json_util.h"

namespace sl::zarr {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

// The object's last key segment, for messages ("'.zarray'").
std::string file_name(const std::string& key) { return key.substr(key.rfind('/') + 1); }

// The JSON object `key` of the store, or nullopt when it does not exist.
std::optional<json> read_json(const ByteStore& bytes, const std::string& key, const std::string& store,
                              const std::string& where) {
  const std::string file = file_name(key);
  if (const std::optional<std::uint64_t> size = bytes.size_if_known(key)) {
    if (const std::string why = json_too_large(*size); !why.empty()) {
      throw InputError(store, where + "'" + file + "' " + why);
    }
  }
  std::optional<std::vector<std::byte>> raw;
  try {
    raw = bytes.read(key, kMaxMetadataBytes);
  } catch (const TransientError& e) {
    throw TransientError(store, where + "cannot read '" + file + "' (" + e.what() + ")");
  } catch (const std::runtime_error& e) {
    throw InputError(store, where + "cannot read '" + file + "' (" + e.what() + ")");
  }
  if (!raw) return std::nullopt;
  if (raw->size() > kMaxJsonBytes) {
    throw InputError(store, where + "'" + file + "' holds more than " + std::to_string(kMaxJsonBytes >> 20) +
                                " MiB of JSON");
  }
  try {
    return json::parse(reinterpret_cast<const char*>(raw->data()), reinterpret_cast<const char*>(raw->data()) + raw->size());
  } catch (const json::exception& e) {
    throw InputError(store, where + "malformed JSON in '" + file + "' (" + e.what() + ")");
  }
}

std::string array_label(const std::string& what, const std::string& array) {
  return "array '" + (what.empty() ? array : what + "/" + array) + "'";
}

vec3 xyz_of(const std::vector<double>& v) {
  const std::size_t n = v.size();
  return vec3(float(v[n - 1]), float(v[n - 2]), float(v[n - 3]));
}

// The product of the "scale" transforms in a coordinateTransformations list (translations ignored:
// sparseleap places level 0 at the origin), or empty when there is none.
std::vector<double> scale_of(const json& j, std::size_t ndim) {
  if (!j.contains("coordinateTransformations")) return {};
  const json& ts = j["coordinateTransformations"];
  if (!ts.is_array()) throw std::runtime_error("coordinateTransformations must be a list");
  std::vector<double> s;
  for (const json& t : ts) {
    if (!t.is_object() || t.value("type", std::string()) != "scale") continue;
    if (!t.contains("scale") || !t["scale"].is_array() || t["scale"].size() != ndim) {
      throw std::runtime_error("scale transform must list one number per axis");
    }
    if (s.empty()) s.assign(ndim, 1.0);
    for (std::size_t i = 0; i < ndim; ++i) {
      if (!t["scale"][i].is_number() || !(t["scale"][i].get<double>() > 0.0)) {
        throw std::runtime_error("scale entries must be positive numbers");
      }
      s[i] *= t["scale"][i].get<double>();
    }
  }
  return s;
}

// The spatial entries (the last three) of a level's scale, after every product, must be usable voxel
// sizes (core/scene/volume.h); `file` is the metadata object that declares them.
void check_scale(const std::vector<double>& s, const std::string& file, std::size_t level) {
  for (std::size_t i = s.size() >= 3 ? s.size() - 3 : 0; i < s.size(); ++i) {
    if (const std::string why = voxel_size_problem(s[i]); !why.empty()) {
      char v[32];
      std::snprintf(v, sizeof v, "%g", s[i]);
      throw std::runtime_error(file + ": dataset " + std::to_string(level) + " scale " + v + " along " +
                               "zyx"[i + 3 - s.size()] + " " + why + " (a voxel size sparseleap can place in world space)");
    }
  }
}

void check_axes(const json& ms, std::size_t ndim) {
  if (!ms.contains("axes")) return;
  const json& axes = ms["axes"];
  if (!axes.is_array() || axes.size() != ndim) {
    throw std::runtime_error("multiscales axes list has " + std::to_string(axes.is_array() ? axes.size() : 0) +
                             " entries for " + std::to_string(ndim) + "-dimensional arrays");
  }
  static const char* kSpatial[3] = {"z", "y", "x"};
  for (std::size_t i = 0; i < 3; ++i) {
    const json& a = axes[ndim - 3 + i];
    const std::string name = a.is_string() ? a.get<std::string>() : a.is_object() ? a.value("name", "") : "";
    if (name != kSpatial[i]) {
      throw std::runtime_error("the last three axes must be z, y, x (found '" + name + "' where '" + kSpatial[i] +
                               "' belongs)");
    }
  }
}

// Zarr v3: named dimensions must agree with the last three axes (z, y, x) and with NGFF 0.5's axes,
// since both name the same array axes.
void check_dimension_names(const ArrayMeta& m, const json* ms) {
  const std::size_t nd = m.dimension_names.size();
  for (std::size_t i = 0; i < nd; ++i) {
    const std::string& n = m.dimension_names[i];
    if (n.empty()) continue;
    if (i + 3 >= nd && n != std::string(1, "zyx"[i + 3 - nd])) {
      throw std::runtime_error("dimension_names " + std::to_string(i) + " is '" + n + "' where '" + "zyx"[i + 3 - nd] +
                               "' belongs (the last three axes must be z, y, x)");
    }
    if (ms && ms->contains("axes") && (*ms)["axes"].is_array() && i < (*ms)["axes"].size()) {
      const json& a = (*ms)["axes"][i];
      const std::string an = a.is_string() ? a.get<std::string>() : a.is_object() ? a.value("name", "") : "";
      if (an != n) throw std::runtime_error("dimension_names '" + n + "' differs from multiscales axis '" + an + "'");
    }
  }
}

// `missing`: the message when the array's metadata object is absent (default "missing NAME").
Level read_level(const ByteStore& bytes, const std::string& group, const std::string& path, const std::string& store,
                 const std::string& what, const std::string& level_label, bool v3, const json* ms,
                 const std::string& missing = {}) {
  Level lv;
  lv.path = path;
  const std::string where = level_label + " (" + array_label(what, path) + "): ";
  const char* name = v3 ? "zarr.json" : ".zarray";
  const std::optional<json> j = read_json(bytes, join_key(group, join_key(path, name)), store, where);
  if (!j) throw InputError(store, missing.empty() ? where + "missing " + name : missing);
  try {
    lv.meta = v3 ? v3::parse_array(*j) : v2::parse_array(*j);
    check_dimension_names(lv.meta, ms);
  } catch (const std::runtime_error& e) {
    throw InputError(store, where + e.what());
  }
  lv.dims = lv.meta.dims();
  return lv;
}

// A multiscale group's metadata node: Zarr v3's zarr.json (a group whose NGFF 0.5 metadata sits in
// attributes.ome, or a bare array) or Zarr v2's .zattrs.
struct GroupNode {
  bool v3 = false;
  bool bare_v3_array = false;
  json attrs;  // the NGFF attributes; null when there are none
};

GroupNode read_group(const ByteStore& bytes, const std::string& prefix, const std::string& store,
                     const std::string& gwhere) {
  GroupNode g;
  const std::optional<json> v3_node = read_json(bytes, join_key(prefix, "zarr.json"), store, gwhere);
  g.v3 = v3_node.has_value();
  if (g.v3) {
    const json& node = *v3_node;
    if (!node.is_object() || !node.contains("zarr_format") || node["zarr_format"] != 3) {
      throw InputError(store, gwhere + "zarr.json: zarr_format must be 3");
    }
    const std::string type = node.value("node_type", std::string());
    if (type == "array") {
      g.bare_v3_array = true;
    } else if (type != "group") {
      throw InputError(store, gwhere + "zarr.json: node_type must be \"group\" or \"array\"");
    } else if (node.contains("attributes") && node["attributes"].is_object() && node["attributes"].contains("ome")) {
      g.attrs = node["attributes"]["ome"];
    }
  } else if (std::optional<json> z = read_json(bytes, join_key(prefix, ".zattrs"), store, gwhere)) {
    g.attrs = std::move(*z);
  }
  return g;
}

// The levels of the group's "multiscales" (NGFF: the first multiscale is the one to use by default),
// read into `m` with their scales (`scales`: per level, empty where the metadata give none).
void read_multiscales(Multiscale& m, const json& mss, bool v3, const std::string& store, const std::string& gwhere,
                      std::vector<std::vector<double>>& scales) {
  try {
    if (!mss.is_array() || mss.empty() || !mss[0].is_object()) {
      throw std::runtime_error("\"multiscales\" must be a non-empty list of objects");
    }
    const json& ms = mss[0];
    if (!ms.contains("datasets") || !ms["datasets"].is_array() || ms["datasets"].empty()) {
      throw std::runtime_error("multiscales has no \"datasets\"");
    }
    for (const json& d : ms["datasets"]) {
      if (!d.is_object() || !d.contains("path") || !d["path"].is_string()) {
        throw std::runtime_error("every dataset needs a string \"path\"");
      }
      // A path names an array inside this store (store_key.h), never "../other.zarr".
      const std::string path = d["path"].get<std::string>();
      try {
        store_key(path);
      } catch (const std::runtime_error& e) {
        throw std::runtime_error(std::string("dataset path: ") + e.what());
      }
      m.levels.push_back({path, {}, ivec3(0), vec3(1.0f)});
    }
    if (m.levels.size() > 15) throw std::runtime_error("more than 15 levels");
    for (std::size_t l = 0; l < m.levels.size(); ++l) {
      Level& lv = m.levels[l];
      const std::string label = "level " + std::to_string(l);
      lv = read_level(*m.bytes, m.prefix, lv.path, store, m.what, label, v3, &ms);
      if (l == 0) check_axes(ms, lv.meta.shape.size());
      std::vector<double> s = scale_of(ms["datasets"][l], lv.meta.shape.size());
      const std::vector<double> global = scale_of(ms, lv.meta.shape.size());
      if (!s.empty() && !global.empty()) {
        for (std::size_t i = 0; i < s.size(); ++i) s[i] *= global[i];
      }
      check_scale(s, v3 ? join_key(m.prefix, "zarr.json") : join_key(m.prefix, ".zattrs"), l);
      scales.push_back(s);
      if (!s.empty()) lv.scale = xyz_of(s);
    }
  } catch (const std::runtime_error& e) {
    if (dynamic_cast<const InputError*>(&e)) throw;
    throw InputError(store, gwhere + "multiscales: " + e.what());
  }
}

// A group without multiscales: a bare array is its own one level (v3: zarr.json; v2: .zarray).
void read_bare_array(Multiscale& m, const GroupNode& g, const std::string& store, const std::string& gwhere,
                     std::vector<std::vector<double>>& scales) {
  if (g.v3) {
    if (!g.bare_v3_array) {
      throw InputError(store, gwhere + "zarr.json is a group without attributes.ome.multiscales: not an image store");
    }
    m.levels.push_back(read_level(*m.bytes, m.prefix, ".", store, m.what, "level 0", true, nullptr));
  } else {
    m.levels.push_back(read_level(*m.bytes, m.prefix, ".", store, m.what, "level 0", false, nullptr,
                                  gwhere + "no OME-Zarr multiscales in .zattrs and no .zarray: not an image store"));
  }
  scales.emplace_back();
}

// Each level must be a 2x reduction of the one before (DESIGN.md "Data model"), of the same dtype.
void check_halving(const Multiscale& m, const std::vector<std::vector<double>>& scales, const std::string& store) {
  for (std::size_t l = 1; l < m.levels.size(); ++l) {
    const Level& a = m.levels[l - 1];
    const Level& b = m.levels[l];
    const std::string where = level_name(m, int(l)) + ": ";
    if (b.meta.type != a.meta.type || b.meta.ndim() != a.meta.ndim()) {
      throw InputError(store, where + "dtype or dimensionality differs from level " + std::to_string(l - 1) + "'s");
    }
    for (int i = 0; i < 3; ++i) {
      const int p = a.dims[i], c = b.dims[i];
      if (c != (p + 1) / 2 && !(c == p / 2 && c > 0)) {
        throw InputError(store, where + "shape " + std::to_string(b.dims.x) + "x" + std::to_string(b.dims.y) + "x" +
                                    std::to_string(b.dims.z) + " is not a 2x reduction of level " + std::to_string(l - 1) +
                                    "'s " + std::to_string(a.dims.x) + "x" +
                                    std::to_string(a.dims.y) + "x" + std::to_string(a.dims.z) +
                                    " (sparseleap needs every level to halve x, y and z)");
      }
      if (!scales[l].empty() && !scales[l - 1].empty()) {
        const float r = b.scale[i] / a.scale[i];
        if (std::abs(r - 2.0f) > 0.02f) {
          throw InputError(store, where + "scale is " + std::to_string(r) + "x level " + std::to_string(l - 1) +
                                      "'s along " + "xyz"[i] + "; sparseleap needs 2x per level");
        }
      }
    }
  }
}

// Level 0's dims, spacing and type, as the volume's description.
void set_desc(Multiscale& m, const std::string& store) {
  m.desc.dims = m.levels[0].dims;
  m.desc.spacing = m.levels[0].scale;
  m.desc.type = m.levels[0].meta.type;
  // Out-of-core volumes may exceed memory, not 64-bit byte counts (each dim is < 2^31 already).
  std::uint64_t total = 0;
  const bool wraps = __builtin_mul_overflow(std::uint64_t(m.desc.dims.x) * std::uint64_t(m.desc.dims.y),
                                            std::uint64_t(m.desc.dims.z) * std::uint64_t(voxel_size(m.desc.type)), &total);
  if (wraps || total >= (std::uint64_t(1) << 63)) {
    throw InputError(store, level_name(m, 0) + ": shape " + std::to_string(m.desc.dims.x) + "x" +
                                std::to_string(m.desc.dims.y) + "x" + std::to_string(m.desc.dims.z) +
                                " overflows a 64-bit byte count");
  }
  validate_desc(m.desc, store, std::numeric_limits<std::uint64_t>::max());
}

}  // namespace

ivec3 ArrayMeta::dims() const {
  const std::size_t n = shape.size();
  return ivec3(int(shape[n - 1]), int(shape[n - 2]), int(shape[n - 3]));
}
ivec3 ArrayMeta::chunk_dims() const {
  const std::size_t n = chunks.size();
  return ivec3(int(chunks[n - 1]), int(chunks[n - 2]), int(chunks[n - 3]));
}
std::size_t ArrayMeta::chunk_bytes() const {
  // Checked when the metadata were parsed (at most kMaxChunkBytes); checked again, it costs nothing.
  return std::size_t(checked_product(std::span<const std::int64_t>(chunks), "decoded chunk bytes", std::uint64_t(voxel_size(type))));
}
std::string ArrayMeta::chunk_key(ivec3 c) const {
  std::string k;
  for (int i = 0; i < ndim() - 3; ++i) k += std::string("0") + separator;
  return k + std::to_string(c.z) + separator + std::to_string(c.y) + separator + std::to_string(c.x);
}

std::string describe(const ArrayMeta& m) { return m.v3 ? m.v3->describe() : describe(m.compressor); }

std::string level_name(const Multiscale& m, int level) {
  const std::string& p = m.levels[std::size_t(level)].path;
  return "level " + std::to_string(level) + " (array '" + (m.what.empty() ? p : m.what + "/" + p) + "')";
}

std::string join_key(const std::string& prefix, const std::string& key) {
  if (prefix.empty() || prefix == ".") return key == "." ? std::string() : key;
  if (key.empty() || key == ".") return prefix;
  return prefix.back() == '/' ? prefix + key : prefix + "/" + key;
}

namespace {

// A member of an unexpected type (a number where a name belongs) that reaches one of nlohmann's typed
// reads is the metadata's fault like every other refusal here: one InputError naming the store.
template <class F> auto typed_json(const std::string& store, const std::string& where, F&& f) -> decltype(f()) {
  try {
    return f();
  } catch (const json::exception& e) {
    throw InputError(store, where + "unexpected JSON type (" + json_error_text(e) + ")");
  }
}

Multiscale open_multiscale_checked(std::shared_ptr<const ByteStore> bytes, const std::string& prefix,
                                   const std::string& store, const std::string& what);
StoreInfo open_store_checked(std::shared_ptr<const ByteStore> bytes, const std::string& path);

}  // namespace

Multiscale open_multiscale(std::shared_ptr<const ByteStore> bytes, const std::string& prefix, const std::string& store,
                           const std::string& what) {
  return typed_json(store, what.empty() ? "" : "group '" + what + "': ",
                    [&] { return open_multiscale_checked(std::move(bytes), prefix, store, what); });
}

StoreInfo open_store(std::shared_ptr<const ByteStore> bytes, const std::string& path) {
  return typed_json(path, "", [&] { return open_store_checked(std::move(bytes), path); });
}

namespace {

Multiscale open_multiscale_checked(std::shared_ptr<const ByteStore> bytes, const std::string& prefix,
                                   const std::string& store, const std::string& what) {
  SL_CHECK(bytes != nullptr);
  Multiscale m;
  m.bytes = bytes;
  m.prefix = prefix;
  m.what = what;
  const std::string gwhere = what.empty() ? "" : "group '" + what + "': ";
  std::vector<std::vector<double>> scales;
  const GroupNode group = read_group(*bytes, prefix, store, gwhere);
  if (group.attrs.is_object() && group.attrs.contains("multiscales")) {
    read_multiscales(m, group.attrs["multiscales"], group.v3, store, gwhere, scales);
  }
  if (m.levels.empty()) read_bare_array(m, group, store, gwhere, scales);
  check_halving(m, scales, store);
  set_desc(m, store);
  return m;
}

// The max pyramid the root's attributes declare (StoreInfo::max), checked against the image: its first
// level must be the image's level 1 (dims halved, same type).
std::optional<Multiscale> open_max_pyramid(const std::shared_ptr<const ByteStore>& bytes, const Multiscale& image,
                                           const std::string& path) {
  const bool v3 = image.levels[0].meta.v3 != nullptr;
  const std::optional<json> node = read_json(*bytes, v3 ? "zarr.json" : ".zattrs", path, "");
  if (!node || !node->is_object()) return std::nullopt;
  const json& attrs = v3 ? node->value("attributes", json::object()) : *node;
  if (!attrs.is_object() || !attrs.contains("sparseleap") || !attrs["sparseleap"].is_object() ||
      !attrs["sparseleap"].contains("max_pyramid")) {
    return std::nullopt;
  }
  const json& g = attrs["sparseleap"]["max_pyramid"];
  if (!g.is_string() || g.get<std::string>().empty()) {
    throw InputError(path, "\"sparseleap\": \"max_pyramid\" must name a group");
  }
  const std::string group = g.get<std::string>();
  Multiscale m = open_multiscale(bytes, group + "/", path, group);
  if (m.desc.dims != (image.desc.dims + 1) / 2 || m.desc.type != image.desc.type) {
    throw InputError(path, "max pyramid '" + group + "' must start at the image's level 1 (half its dims, same type)");
  }
  return m;
}

StoreInfo open_store_checked(std::shared_ptr<const ByteStore> bytes, const std::string& path) {
  StoreInfo s;
  s.path = path;
  s.image = open_multiscale(bytes, "", path, "");
  s.max = open_max_pyramid(bytes, s.image, path);
  json j;
  if (const std::optional<json> node = read_json(*bytes, "labels/zarr.json", path, "group 'labels': ")) {
    // NGFF 0.5: the label names sit in the labels group's attributes.ome.
    if (node->is_object() && node->contains("attributes") && (*node)["attributes"].is_object() &&
        (*node)["attributes"].contains("ome")) {
      j = (*node)["attributes"]["ome"];
    }
  } else if (std::optional<json> z = read_json(*bytes, "labels/.zattrs", path, "group 'labels': ")) {
    j = std::move(*z);
  }
  if (j.is_object() && j.contains("labels")) {
    if (!j["labels"].is_array()) throw InputError(path, "group 'labels': \"labels\" must be a list of names");
    for (const json& n : j["labels"]) {
      if (!n.is_string()) throw InputError(path, "group 'labels': \"labels\" must be a list of names");
      s.label_names.push_back(n.get<std::string>());
    }
  }
  if (!s.label_names.empty()) {
    s.labels = open_multiscale(bytes, "labels/" + s.label_names[0], path, "labels/" + s.label_names[0]);
    if (s.labels->desc.dims != s.image.desc.dims) {
      throw InputError(path, "label image 'labels/" + s.label_names[0] + "' dims differ from the image's");
    }
    if (s.labels->desc.type == VoxelType::F32) {
      throw InputError(path, "label image 'labels/" + s.label_names[0] + "' must be of an integer type");
    }
  }
  return s;
}

}  // namespace

StoreInfo open_store(const std::string& path) {
  if (is_url(path)) return open_store(open_byte_store(path), path);
  std::string p = path;
  while (p.size() > 1 && p.back() == '/') p.pop_back();
  const fs::path dir(p);
  std::error_code ec;
  const fs::file_status st = fs::status(dir, ec);
  if (ec && ec != std::errc::no_such_file_or_directory) throw InputError(path, "cannot open the store (" + ec.message() + ")");
  if (!fs::exists(st)) throw InputError(path, "no such store (directory)");
  if (!fs::is_directory(st)) throw InputError(path, "a Zarr store must be a directory");
  return open_store(std::make_shared<LocalByteStore>(p), path);
}

}  // namespace sl::zarr
