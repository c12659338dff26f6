#include "cache/formats/zarr/array.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>

#include "cache/formats/zarr/v3_chunk.h"
#include "core/scene/voxel_dispatch.h"
#include "core/util/error.h"

namespace sl::zarr {
namespace {

void swap_bytes(std::byte* p, std::size_t count, int size) {
  for (std::size_t i = 0; i < count; ++i, p += size) std::reverse(p, p + size);
}

template <class T> T clamp_fill(double v) {
  if constexpr (std::is_floating_point_v<T>) {
    return T(v);
  } else {
    if (!(v == v)) return T(0);  // NaN in an integer array: 0
    return T(std::clamp(std::round(v), 0.0, double(std::numeric_limits<T>::max())));
  }
}

template <class T> void fill_with(std::vector<std::byte>& b, double v) {
  const T t = clamp_fill<T>(v);
  T* p = reinterpret_cast<T*>(b.data());
  std::fill(p, p + b.size() / sizeof(T), t);
}

ChunkCache::Chunk make_fill_chunk(const ArrayMeta& m) {
  auto b = std::make_shared<std::vector<std::byte>>(m.chunk_bytes());
  dispatch_voxel(m.type, [&](auto tag) { fill_with<decltype(tag)>(*b, m.fill); });
  return b;
}

}  // namespace

ArrayReader::ArrayReader(Multiscale m, std::string store, std::shared_ptr<ChunkCache> cache)
    : m_(std::move(m)), store_(std::move(store)), cache_(std::move(cache)),
      index_cache_(std::make_shared<ChunkCache>(kShardIndexCacheBytes)) {
  SL_CHECK(cache_ != nullptr && m_.bytes != nullptr);
  for (const Level& l : m_.levels) fill_.push_back(make_fill_chunk(l.meta));
}

std::string ArrayReader::array_dir(int level) const {
  const std::string d = join_key(m_.prefix, m_.levels[std::size_t(level)].path);
  return d.empty() ? d : d + "/";
}

ChunkCache::Chunk ArrayReader::chunk(int level, ivec3 c) const {
  const Level& lv = m_.levels[std::size_t(level)];
  if (lv.meta.v3) return chunk_v3(level, c);
  const std::string rel = lv.meta.chunk_key(c);
  const std::string object = array_dir(level) + rel;
  const std::string key = store_ + "/" + object;
  if (ChunkCache::Chunk hit = cache_->get(key)) return hit;

  const auto where = [&] { return level_name(m_, level) + " chunk '" + rel + "': "; };
  std::optional<std::vector<std::byte>> raw;
  try {
    raw = m_.bytes->read(object, kMaxChunkObjectBytes);
  } catch (const TransientError& e) {
    throw TransientError(store_, where() + e.what());  // the brick loader retries it (core/util/error.h)
  } catch (const std::runtime_error& e) {
    throw InputError(store_, where() + e.what());
  }
  // Zarr v2: a chunk that was never written holds the fill value everywhere.
  if (!raw) {
    cache_->put_missing(key, fill_[std::size_t(level)]);
    return fill_[std::size_t(level)];
  }

  auto out = std::make_shared<std::vector<std::byte>>(lv.meta.chunk_bytes());
  try {
    decode(lv.meta.compressor, *raw, *out);
  } catch (const std::runtime_error& e) {
    throw InputError(store_, where() + e.what());
  }
  const int size = voxel_size(lv.meta.type);
  if (size > 1 && lv.meta.big_endian != (std::endian::native == std::endian::big)) {
    swap_bytes(out->data(), out->size() / std::size_t(size), size);
  }
  ChunkCache::Chunk result = std::move(out);
  cache_->put(key, result);
  return result;
}

ChunkCache::Chunk ArrayReader::chunk_v3(int level, ivec3 c) const {
  const Level& lv = m_.levels[std::size_t(level)];
  std::vector<std::int64_t> g(std::size_t(lv.meta.ndim()), 0);
  g[g.size() - 3] = c.z;
  g[g.size() - 2] = c.y;
  g[g.size() - 1] = c.x;
  const std::string dir = array_dir(level);
  const std::string prefix = store_ + "/" + dir;
  const std::string key = prefix + "#" + std::to_string(c.z) + "," + std::to_string(c.y) + "," + std::to_string(c.x);
  if (ChunkCache::Chunk hit = cache_->get(key)) return hit;
  std::optional<std::vector<std::byte>> data;
  try {
    data = v3::read_chunk(*lv.meta.v3, *m_.bytes, dir, g, *index_cache_, prefix);
  } catch (const TransientError& e) {
    throw TransientError(store_, level_name(m_, level) + " " + e.what());
  } catch (const std::runtime_error& e) {
    throw InputError(store_, level_name(m_, level) + " " + e.what());
  }
  if (!data) {
    cache_->put_missing(key, fill_[std::size_t(level)]);
    return fill_[std::size_t(level)];
  }
  ChunkCache::Chunk result = std::make_shared<const std::vector<std::byte>>(std::move(*data));
  cache_->put(key, result);
  return result;
}

void ArrayReader::read_box(int level, ivec3 first, ivec3 n, std::byte* dst) const {
  SL_CHECK(level >= 0 && level < levels());
  const Level& lv = m_.levels[std::size_t(level)];
  const ivec3 sd = lv.dims;
  const ivec3 cd = lv.meta.chunk_dims();
  const std::size_t elem = std::size_t(voxel_size(lv.meta.type));
  SL_CHECK(glm::all(glm::greaterThanEqual(first, ivec3(0))) && glm::all(glm::greaterThan(n, ivec3(0))));
  // Source box: the requested one clamped to the stored shape.
  const ivec3 lo = glm::min(first, sd - 1);
  const ivec3 hi = glm::min(first + n - 1, sd - 1);
  const ivec3 c0 = lo / cd, c1 = hi / cd;
  for (int cz = c0.z; cz <= c1.z; ++cz) {
    for (int cy = c0.y; cy <= c1.y; ++cy) {
      for (int cx = c0.x; cx <= c1.x; ++cx) {
        const ivec3 c(cx, cy, cz);
        const ChunkCache::Chunk ch = chunk(level, c);
        const std::byte* src = ch->data();
        const ivec3 corg = c * cd;
        // Output range along x whose clamped source lies in this chunk: contiguous, since clamping is
        // monotonic; the part past the stored edge repeats the last voxel.
        int ox0 = -1, ox1 = -1;
        for (int x = 0; x < n.x; ++x) {
          const int sx = std::min(first.x + x, sd.x - 1);
          if (sx >= corg.x && sx < corg.x + cd.x) {
            if (ox0 < 0) ox0 = x;
            ox1 = x + 1;
          }
        }
        if (ox0 < 0) continue;
        for (int z = 0; z < n.z; ++z) {
          const int sz = std::min(first.z + z, sd.z - 1);
          if (sz < corg.z || sz >= corg.z + cd.z) continue;
          for (int y = 0; y < n.y; ++y) {
            const int sy = std::min(first.y + y, sd.y - 1);
            if (sy < corg.y || sy >= corg.y + cd.y) continue;
            const std::byte* row =
                src + ((std::size_t(sz - corg.z) * std::size_t(cd.y) + std::size_t(sy - corg.y)) * std::size_t(cd.x)) * elem;
            std::byte* out = dst + ((std::size_t(z) * std::size_t(n.y) + std::size_t(y)) * std::size_t(n.x)) * elem;
            // Unclamped run, then repeats of the edge voxel.
            const int run_end = std::min(ox1, sd.x - first.x);
            if (run_end > ox0) {
              std::memcpy(out + std::size_t(ox0) * elem, row + std::size_t(first.x + ox0 - corg.x) * elem,
                          std::size_t(run_end - ox0) * elem);
            }
            for (int x = std::max(ox0, run_end); x < ox1; ++x) {
              std::memcpy(out + std::size_t(x) * elem, row + std::size_t(sd.x - 1 - corg.x) * elem, elem);
            }
          }
        }
      }
    }
  }
}

}  // namespace sl::zarr
