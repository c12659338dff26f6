#include "cache/formats/zarr/source.h"

#include <cstring>
#include <optional>
#include <nlohmann/json.hpp>

#include "cache/formats/chunked_levels.h"
#include "cache/pyramid.h"
#include "core/util/error.h"

namespace sl {
namespace {

// A whole level of a reader (cache/formats/chunked_levels.h).
Volume read_level(const zarr::ArrayReader& r, int level, const std::string& origin, bool skip_unreadable = false) {
  const zarr::Level& lv = r.multiscale().levels[std::size_t(level)];
  const VolumeDesc d{lv.dims, r.multiscale().desc.spacing * float(1 << level), lv.meta.type};
  return read_chunked_level(
      d, lv.meta.chunk_dims(), [&](ivec3 first, ivec3 n, std::byte* dst) { r.read_box(level, first, n, dst); }, origin,
      skip_unreadable);
}

std::string mib(std::uint64_t b) { return std::to_string((b + (1 << 19)) >> 20) + " MiB"; }

}  // namespace

ZarrVolumeSource::ZarrVolumeSource(const std::string& path, const std::string& labels_path,
                                   std::optional<PyramidKind> pyramid, std::size_t chunk_cache_bytes)
    : name_(path), cache_(std::make_shared<zarr::ChunkCache>(chunk_cache_bytes)) {
  zarr::StoreInfo info = zarr::open_store(path);
  image_ = std::make_unique<zarr::ArrayReader>(info.image, path, cache_);
  // A store of one level has every max level by derivation; a deeper one needs them stored.
  const bool has_max = info.max.has_value() || image_->levels() == 1;
  pyramid_ = pyramid.value_or(has_max ? PyramidKind::Max : PyramidKind::Mean);
  if (pyramid_ == PyramidKind::Max && !has_max) {
    throw InputError(path, "has only mean levels, no max pyramid for --pyramid max (`sparseleap ingest` writes one; "
                           "or use --pyramid mean)");
  }
  if (pyramid_ == PyramidKind::Max && info.max) max_ = std::make_unique<zarr::ArrayReader>(*info.max, path, cache_);
  std::string labels_store = path;
  if (!labels_path.empty()) {
    zarr::StoreInfo li = zarr::open_store(labels_path);
    if (li.image.desc.dims != info.image.desc.dims) {
      throw InputError(labels_path, "label store dims differ from the image's (" + path + ")");
    }
    if (li.image.desc.type == VoxelType::F32) throw InputError(labels_path, "labels must be of an integer type");
    labels_ = std::make_unique<zarr::ArrayReader>(li.image, labels_path, cache_);
    labels_store = labels_path;
  } else if (info.labels) {
    labels_ = std::make_unique<zarr::ArrayReader>(*info.labels, path, cache_);
  }
  if (labels_) {
    // Zarr v2 keeps a group's attributes in .zattrs, v3 in zarr.json's "attributes".
    const zarr::Multiscale& lm = labels_->multiscale();
    const bool v3 = lm.levels[0].meta.v3 != nullptr;
    std::optional<std::vector<std::byte>> raw;
    try {
      raw = lm.bytes->read(zarr::join_key(lm.prefix, v3 ? "zarr.json" : ".zattrs"), kMaxMetadataBytes);
    } catch (const std::runtime_error&) {
      // Read by open_multiscale already; a failure now only loses the shortcut.
    }
    if (raw) {
      try {
        const char* text = reinterpret_cast<const char*>(raw->data());
        const nlohmann::json node = nlohmann::json::parse(text, text + raw->size());
        const nlohmann::json& j = v3 && node.contains("attributes") ? node["attributes"] : node;
        if (j.contains("sparseleap") && j["sparseleap"].contains("max_label")) {
          max_label_attr_ = j["sparseleap"]["max_label"].get<std::uint32_t>();
          has_max_label_attr_ = true;
        }
      } catch (const nlohmann::json::exception&) {
        // Checked by open_multiscale already; an odd attribute only loses the shortcut.
      }
    }
  }
  const auto base = [&](const zarr::ArrayReader& r, const std::string& store) {
    const int c = r.levels() - 1;
    const zarr::Level& lv = r.multiscale().levels[std::size_t(c)];
    VolumeDesc d{lv.dims, vec3(1.0f), lv.meta.type};
    if (d.byte_size() > kMaxDerivedBaseBytes) {
      throw InputError(store, zarr::level_name(r.multiscale(), c) + " is the coarsest stored level and holds " +
                                  mib(d.byte_size()) + "; coarser levels are derived in memory from at most " +
                                  mib(kMaxDerivedBaseBytes) + " (rewrite the store with `sparseleap ingest` for a "
                                  "full pyramid)");
    }
    return read_level(r, c, store);
  };
  derived_ = derive_levels(base(max_ ? *max_ : *image_, path), intensity_reduction(pyramid_));
  if (labels_) derived_labels_ = derive_levels(base(*labels_, labels_store), reduce_mode);
}

void ZarrVolumeSource::read_brick(const BrickLayout& layout, BrickId id, std::span<std::byte> out_intensity,
                                  std::span<std::byte> out_labels) const {
  check_request(layout, id, out_intensity, out_labels);
  const auto one = [&](const zarr::ArrayReader& r, const std::vector<Volume>& derived, std::span<std::byte> out) {
    const ReadLevelBox read = [&](int l, ivec3 first, ivec3 n, std::byte* dst) { r.read_box(l, first, n, dst); };
    read_chunked_brick(layout, id, r.levels(), r.type(), read, derived, out);
  };
  if (max_ && id.level() > 0) {
    // The max group's level l - 1 is the image's level l.
    const ReadLevelBox read = [&](int l, ivec3 first, ivec3 n, std::byte* dst) { max_->read_box(l - 1, first, n, dst); };
    read_chunked_brick(layout, id, max_->levels() + 1, max_->type(), read, derived_, out_intensity);
  } else {
    one(*image_, derived_, out_intensity);
  }
  if (!out_labels.empty()) one(*labels_, derived_labels_, out_labels);
}

std::uint32_t ZarrVolumeSource::max_label() const {
  if (!labels_) return 0;
  if (has_max_label_attr_) return max_label_attr_;
  for (int l = 0; l < labels_->levels(); ++l) {
    const zarr::Level& lv = labels_->multiscale().levels[std::size_t(l)];
    if (VolumeDesc{lv.dims, vec3(1.0f), lv.meta.type}.byte_size() <= (std::uint64_t(256) << 20)) {
      return sl::max_label(read_level(*labels_, l, name_, true));
    }
  }
  return derived_labels_.empty() ? 0 : sl::max_label(derived_labels_.front());
}

vec2 ZarrVolumeSource::value_range_estimate() const {
  for (int l = 0; l < image_->levels(); ++l) {
    const zarr::Level& lv = image_->multiscale().levels[std::size_t(l)];
    if (VolumeDesc{lv.dims, vec3(1.0f), lv.meta.type}.byte_size() <= (std::uint64_t(64) << 20)) {
      return value_range(read_level(*image_, l, name_));
    }
  }
  return value_range(derived_.front());
}

Volume read_zarr_volume(const std::string& path, bool labels) {
  zarr::StoreInfo info = zarr::open_store(path);
  if (labels && !info.labels) throw InputError(path, "store has no labels/ group");
  const zarr::Multiscale& m = labels ? *info.labels : info.image;
  validate_desc(m.desc, path);
  // No caching: each chunk is read exactly once.
  zarr::ArrayReader r(m, path, std::make_shared<zarr::ChunkCache>(0));
  Volume v = read_level(r, 0, path);
  v.set_spacing(m.desc.spacing);
  return v;
}

}  // namespace sl
