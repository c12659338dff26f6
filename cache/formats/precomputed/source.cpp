#include "cache/formats/precomputed/source.h"

#include <cstring>

#include "cache/formats/chunked_levels.h"
#include "cache/formats/precomputed/chunk.h"
#include "cache/formats/precomputed/shard.h"
#include "cache/pyramid.h"
#include "cache/stores/store_url.h"
#include "core/util/checked.h"
#include "core/util/error.h"

namespace sl {
namespace precomputed {
namespace {

std::string range_text(int lo, int hi) { return std::to_string(lo) + "-" + std::to_string(hi); }

}  // namespace

VolumeReader::VolumeReader(std::shared_ptr<const ByteStore> bytes, std::string name,
                           std::shared_ptr<zarr::ChunkCache> cache)
    : bytes_(std::move(bytes)), name_(std::move(name)), cache_(std::move(cache)),
      index_cache_(std::make_shared<zarr::ChunkCache>(zarr::kShardIndexCacheBytes)) {
  SL_CHECK(bytes_ != nullptr && cache_ != nullptr);
  std::optional<std::vector<std::byte>> text;
  try {
    text = bytes_->read("info", kMaxMetadataBytes);
  } catch (const TransientError& e) {
    throw TransientError(name_, std::string("info: ") + e.what());
  } catch (const std::runtime_error& e) {
    throw InputError(name_, std::string("info: ") + e.what());
  }
  if (!text) throw InputError(name_, "no 'info' file: not a Neuroglancer precomputed volume");
  info_ = parse_info(std::string(reinterpret_cast<const char*>(text->data()), text->size()), name_);
}

VolumeDesc VolumeReader::level_desc(int level) const {
  return VolumeDesc{info_.scales[std::size_t(level)].size, info_.desc().spacing * float(1 << level), type()};
}

std::string VolumeReader::chunk_name(int level, ivec3 c) const {
  const Scale& s = info_.scales[std::size_t(level)];
  const ivec3 lo = s.voxel_offset + c * s.chunk, hi = glm::min(lo + s.chunk, s.voxel_offset + s.size);
  std::string t = range_text(lo.x, hi.x) + "_" + range_text(lo.y, hi.y) + "_" + range_text(lo.z, hi.z);
  if (s.sharding) {
    const std::uint64_t id = compressed_morton_code(c, s.grid());
    const ShardLocation loc = locate_chunk(*s.sharding, id);
    t += " (id " + std::to_string(id) + ", shard '" + loc.file + "' minishard " + std::to_string(loc.minishard) + ")";
  }
  return t;
}

std::optional<std::vector<std::byte>> VolumeReader::chunk_data(int level, ivec3 c) const {
  const Scale& s = info_.scales[std::size_t(level)];
  if (!s.sharding) {
    const std::size_t n_vox = std::size_t(s.chunk.x) * std::size_t(s.chunk.y) * std::size_t(s.chunk.z);
    return bytes_->read(s.key + "/" + chunk_name(level, c), 16 * n_vox + (std::size_t(1) << 20));
  }
  const Sharding& sh = *s.sharding;
  const std::uint64_t id = compressed_morton_code(c, s.grid());
  const ShardLocation loc = locate_chunk(sh, id);
  const std::string file = s.key + "/" + loc.file;
  // The decoded minishard index, cached: the chunks of one minishard share it.
  const std::string ikey = name_ + "#" + file + "#" + std::to_string(loc.minishard);
  zarr::ChunkCache::Chunk index = index_cache_->get(ikey);
  if (!index) {
    const std::optional<std::vector<std::byte>> entry = bytes_->read_range(file, 16 * loc.minishard, 16);
    if (!entry) return std::nullopt;  // no shard file: nothing of it was written
    const ByteRange r = decode_shard_index_entry(sh, *entry);
    std::vector<MinishardEntry> entries;
    if (r.end > r.start) {
      // Bounded before it is read: the entry is the shard file's word, not ours.
      checked_bound(r.end - r.start, kMaxIndexBytes, "minishard index");
      const std::optional<std::vector<std::byte>> stored = bytes_->read_range(file, r.start, r.end - r.start);
      if (!stored) return std::nullopt;
      entries = decode_minishard_index(sh, *stored, r);
    }
    auto b = std::make_shared<std::vector<std::byte>>(entries.size() * sizeof(MinishardEntry));
    if (!entries.empty()) std::memcpy(b->data(), entries.data(), b->size());
    index = std::move(b);
    index_cache_->put(ikey, index);
  }
  const auto* e = reinterpret_cast<const MinishardEntry*>(index->data());
  for (std::size_t i = 0, n = index->size() / sizeof(MinishardEntry); i < n; ++i) {
    if (e[i].chunk_id != id) continue;
    const std::size_t n_vox = std::size_t(s.chunk.x) * std::size_t(s.chunk.y) * std::size_t(s.chunk.z);
    // At most what the largest encoding of the chunk takes (16 bytes a voxel and a table bound the
    // compressed_segmentation form, the largest), before the minishard's size is trusted to allocate.
    checked_bound(e[i].size, 16 * n_vox + (std::size_t(1) << 20), "chunk");
    std::optional<std::vector<std::byte>> data = bytes_->read_range(file, e[i].offset, e[i].size);
    if (data && sh.gzip_data) {
      // Raw: exactly the chunk; compressed_segmentation: at most 32 bits and a table entry per voxel.
      data = gunzip(*data, s.encoding == Encoding::Raw ? n_vox * std::size_t(data_type_size(info_.data_type))
                                                       : 16 * n_vox + (std::size_t(1) << 20));
    }
    return data;
  }
  return std::nullopt;  // not in its minishard: never written
}

zarr::ChunkCache::Chunk VolumeReader::chunk(int level, ivec3 c) const {
  const std::string key = name_ + "#" + std::to_string(level) + "#" + std::to_string(c.x) + "," + std::to_string(c.y) +
                          "," + std::to_string(c.z);
  if (zarr::ChunkCache::Chunk hit = cache_->get(key)) return hit;
  const Scale& s = info_.scales[std::size_t(level)];
  const auto where = [&] { return s.name(level) + " chunk " + chunk_name(level, c) + ": "; };
  zarr::ChunkCache::Chunk result;
  try {
    const std::optional<std::vector<std::byte>> data = chunk_data(level, c);
    if (!data) return nullptr;
    const ivec3 shape = glm::min(s.chunk, s.size - c * s.chunk);
    result = std::make_shared<const std::vector<std::byte>>(decode_chunk(info_, s, *data, shape));
  } catch (const TransientError& e) {
    throw TransientError(name_, where() + e.what());
  } catch (const std::runtime_error& e) {
    throw InputError(name_, where() + e.what());
  }
  cache_->put(key, result);
  return result;
}

void VolumeReader::read_box(int level, ivec3 first, ivec3 n, std::byte* dst) const {
  SL_CHECK(level >= 0 && level < levels());
  const Scale& s = info_.scales[std::size_t(level)];
  const ivec3 sd = s.size, cd = s.chunk;
  const std::size_t elem = std::size_t(voxel_size(type()));
  SL_CHECK(glm::all(glm::greaterThanEqual(first, ivec3(0))) && glm::all(glm::greaterThan(n, ivec3(0))));
  const ivec3 c0 = glm::min(first, sd - 1) / cd, c1 = glm::min(first + n - 1, sd - 1) / cd;
  for (int cz = c0.z; cz <= c1.z; ++cz)
    for (int cy = c0.y; cy <= c1.y; ++cy)
      for (int cx = c0.x; cx <= c1.x; ++cx) {
        const ivec3 c(cx, cy, cz), org = c * cd;
        const ivec3 cs = glm::min(cd, sd - org);  // stored shape: edge chunks are clipped
        const zarr::ChunkCache::Chunk ch = chunk(level, c);  // null: not stored, zeros
        // Every output voxel whose clamped source voxel lies in this chunk.
        for (int z = 0; z < n.z; ++z) {
          const int sz = std::min(first.z + z, sd.z - 1) - org.z;
          if (sz < 0 || sz >= cs.z) continue;
          for (int y = 0; y < n.y; ++y) {
            const int sy = std::min(first.y + y, sd.y - 1) - org.y;
            if (sy < 0 || sy >= cs.y) continue;
            const std::size_t row = (std::size_t(sz) * std::size_t(cs.y) + std::size_t(sy)) * std::size_t(cs.x);
            std::byte* out = dst + (std::size_t(z) * std::size_t(n.y) + std::size_t(y)) * std::size_t(n.x) * elem;
            for (int x = 0; x < n.x; ++x) {
              const int sx = std::min(first.x + x, sd.x - 1) - org.x;
              if (sx < 0 || sx >= cs.x) continue;
              if (ch) {
                std::memcpy(out + std::size_t(x) * elem, ch->data() + (row + std::size_t(sx)) * elem, elem);
              } else {
                std::memset(out + std::size_t(x) * elem, 0, elem);
              }
            }
          }
        }
      }
}

}  // namespace precomputed

namespace {

std::string mib(std::uint64_t b) { return std::to_string((b + (1 << 19)) >> 20) + " MiB"; }

}  // namespace

PrecomputedVolumeSource::PrecomputedVolumeSource(std::shared_ptr<const ByteStore> bytes, std::string name,
                                                 std::shared_ptr<const ByteStore> labels_bytes, std::string labels_name,
                                                 std::size_t chunk_cache_bytes)
    : cache_(std::make_shared<zarr::ChunkCache>(chunk_cache_bytes)) {
  image_ = std::make_unique<precomputed::VolumeReader>(std::move(bytes), std::move(name), cache_);
  desc_ = image_->info().desc();
  if (labels_bytes) {
    labels_ = std::make_unique<precomputed::VolumeReader>(std::move(labels_bytes), std::move(labels_name), cache_);
    if (labels_->info().desc().dims != desc_.dims) {
      throw InputError(labels_->name(), "label volume size differs from the image's (" + image_->name() + ")");
    }
    if (labels_->info().data_type == precomputed::DataType::F32) {
      throw InputError(labels_->name(), "labels must be of an integer type, not float32");
    }
  }
  const auto base = [](const precomputed::VolumeReader& r) {
    const int c = r.levels() - 1;
    const VolumeDesc d = r.level_desc(c);
    if (d.byte_size() > kMaxDerivedBaseBytes) {
      throw InputError(r.name(), r.info().scales[std::size_t(c)].name(c) + " is the coarsest scale and holds " +
                                     mib(d.byte_size()) + "; coarser levels are derived in memory from at most " +
                                     mib(kMaxDerivedBaseBytes) + " (add coarser scales)");
    }
    return read_chunked_level(
        d, r.info().scales[std::size_t(c)].chunk,
        [&](ivec3 first, ivec3 n, std::byte* dst) { r.read_box(c, first, n, dst); }, r.name());
  };
  derived_ = derive_levels(base(*image_), reduce_mean);
  if (labels_) derived_labels_ = derive_levels(base(*labels_), reduce_mode);
}

void PrecomputedVolumeSource::read_brick(const BrickLayout& layout, BrickId id, std::span<std::byte> out_intensity,
                                         std::span<std::byte> out_labels) const {
  check_request(layout, id, out_intensity, out_labels);
  const auto one = [&](const precomputed::VolumeReader& r, const std::vector<Volume>& derived, std::span<std::byte> out) {
    const ReadLevelBox read = [&](int l, ivec3 first, ivec3 n, std::byte* dst) { r.read_box(l, first, n, dst); };
    read_chunked_brick(layout, id, r.levels(), r.type(), read, derived, out);
  };
  one(*image_, derived_, out_intensity);
  if (!out_labels.empty()) one(*labels_, derived_labels_, out_labels);
}

namespace {

// The finest level of `r` of at most `max_bytes`, read whole; nullopt when none is that small.
std::optional<Volume> finest_small_level(const precomputed::VolumeReader& r, std::uint64_t max_bytes, bool skip_unreadable) {
  for (int l = 0; l < r.levels(); ++l) {
    const VolumeDesc d = r.level_desc(l);
    if (d.byte_size() <= max_bytes) {
      return read_chunked_level(
          d, r.info().scales[std::size_t(l)].chunk,
          [&](ivec3 first, ivec3 n, std::byte* dst) { r.read_box(l, first, n, dst); }, r.name(), skip_unreadable);
    }
  }
  return std::nullopt;
}

}  // namespace

std::uint32_t PrecomputedVolumeSource::max_label() const {
  if (!labels_) return 0;
  if (const std::optional<Volume> v = finest_small_level(*labels_, std::uint64_t(256) << 20, true)) return sl::max_label(*v);
  return derived_labels_.empty() ? 0 : sl::max_label(derived_labels_.front());
}

vec2 PrecomputedVolumeSource::value_range_estimate() const {
  if (const std::optional<Volume> v = finest_small_level(*image_, std::uint64_t(64) << 20, false)) return value_range(*v);
  return value_range(derived_.front());
}

std::shared_ptr<PrecomputedVolumeSource> open_precomputed(const std::string& dir, const std::string& labels_dir) {
  return std::make_shared<PrecomputedVolumeSource>(
      open_byte_store(dir), dir,
      labels_dir.empty() ? nullptr : open_byte_store(labels_dir), labels_dir);
}

VolumeDesc read_precomputed_desc(const std::string& dir) {
  return precomputed::VolumeReader(open_byte_store(dir), dir, std::make_shared<zarr::ChunkCache>(0))
      .info()
      .desc();
}

Volume read_precomputed_volume(const std::string& dir) {
  // No caching: each chunk is read exactly once.
  const precomputed::VolumeReader r(open_byte_store(dir), dir, std::make_shared<zarr::ChunkCache>(0));
  validate_desc(r.info().desc(), dir);
  Volume v = read_chunked_level(
      r.level_desc(0), r.info().scales[0].chunk,
      [&](ivec3 first, ivec3 n, std::byte* dst) { r.read_box(0, first, n, dst); }, dir);
  v.set_spacing(r.info().desc().spacing);
  return v;
}

}  // namespace sl
