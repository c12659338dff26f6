#include "cache/pyramid.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <unordered_map>

#include "core/util/config.h"
#include "core/util/error.h"
#include "core/util/parallel.h"
#include "core/scene/voxel_dispatch.h"

namespace sl {
namespace {

template <class T>
void mean_rows(const T* src, ivec3 sd, T* dst, int z0, int z1) {
  const ivec3 dd = (sd + 1) / 2;
  for (int z = z0; z < z1; ++z) {
    for (int y = 0; y < dd.y; ++y) {
      for (int x = 0; x < dd.x; ++x) {
        double fsum = 0.0;
        std::uint64_t isum = 0;
        int n = 0;
        for (int k = 2 * z; k < std::min(2 * z + 2, sd.z); ++k) {
          for (int j = 2 * y; j < std::min(2 * y + 2, sd.y); ++j) {
            const T* row = src + (std::size_t(k) * std::size_t(sd.y) + std::size_t(j)) * std::size_t(sd.x);
            for (int i = 2 * x; i < std::min(2 * x + 2, sd.x); ++i) {
              if constexpr (std::is_floating_point_v<T>) {
                fsum += double(row[i]);
              } else {
                isum += std::uint64_t(row[i]);
              }
              ++n;
            }
          }
        }
        T& out = dst[(std::size_t(z) * std::size_t(dd.y) + std::size_t(y)) * std::size_t(dd.x) + std::size_t(x)];
        if constexpr (std::is_floating_point_v<T>) {
          out = T(fsum / double(n));
        } else {
          out = T((isum + std::uint64_t(n / 2)) / std::uint64_t(n));
        }
      }
    }
  }
}

template <class T>
void mode_rows(const T* src, ivec3 sd, T* dst, int z0, int z1) {
  const ivec3 dd = (sd + 1) / 2;
  for (int z = z0; z < z1; ++z) {
    for (int y = 0; y < dd.y; ++y) {
      for (int x = 0; x < dd.x; ++x) {
        T v[8];
        int n = 0;
        for (int k = 2 * z; k < std::min(2 * z + 2, sd.z); ++k) {
          for (int j = 2 * y; j < std::min(2 * y + 2, sd.y); ++j) {
            const T* row = src + (std::size_t(k) * std::size_t(sd.y) + std::size_t(j)) * std::size_t(sd.x);
            for (int i = 2 * x; i < std::min(2 * x + 2, sd.x); ++i) {
              if (row[i] != 0) v[n++] = row[i];
            }
          }
        }
        T best = 0;
        int best_count = 0;
        for (int a = 0; a < n; ++a) {
          int c = 0;
          for (int b = 0; b < n; ++b) c += v[b] == v[a];
          if (c > best_count || (c == best_count && v[a] > best)) {
            best = v[a];
            best_count = c;
          }
        }
        dst[(std::size_t(z) * std::size_t(dd.y) + std::size_t(y)) * std::size_t(dd.x) + std::size_t(x)] = best;
      }
    }
  }
}

// The 2³ (or fewer, at odd edges) level-l voxels below level l + 1 voxel (x, y, z), in a fixed order.
template <class T, class Fn>
void for_each_below(const T* src, ivec3 sd, int x, int y, int z, Fn&& fn) {
  for (int k = 2 * z; k < std::min(2 * z + 2, sd.z); ++k) {
    for (int j = 2 * y; j < std::min(2 * y + 2, sd.y); ++j) {
      const T* row = src + (std::size_t(k) * std::size_t(sd.y) + std::size_t(j)) * std::size_t(sd.x);
      for (int i = 2 * x; i < std::min(2 * x + 2, sd.x); ++i) fn(row[i]);
    }
  }
}

template <bool kMax, class T>
void bound_rows(const T* src, ivec3 sd, T* dst, int z0, int z1) {
  const ivec3 dd = (sd + 1) / 2;
  for (int z = z0; z < z1; ++z) {
    for (int y = 0; y < dd.y; ++y) {
      int x = 0;
      if constexpr (!std::is_floating_point_v<T>) {
        // Whole 2³ groups, four source rows at a time (integers: the order of comparison is moot).
        if (2 * z + 1 < sd.z && 2 * y + 1 < sd.y) {
          const auto row = [&](int k, int j) {
            return src + (std::size_t(k) * std::size_t(sd.y) + std::size_t(j)) * std::size_t(sd.x);
          };
          const T *r0 = row(2 * z, 2 * y), *r1 = row(2 * z, 2 * y + 1), *r2 = row(2 * z + 1, 2 * y),
                  *r3 = row(2 * z + 1, 2 * y + 1);
          T* out = dst + (std::size_t(z) * std::size_t(dd.y) + std::size_t(y)) * std::size_t(dd.x);
          const auto pick = [](T a, T b) { return kMax ? (a > b ? a : b) : (a < b ? a : b); };
          for (; x < sd.x / 2; ++x) {
            const int i = 2 * x;
            out[x] = pick(pick(pick(r0[i], r0[i + 1]), pick(r1[i], r1[i + 1])),
                          pick(pick(r2[i], r2[i + 1]), pick(r3[i], r3[i + 1])));
          }
        }
      }
      for (; x < dd.x; ++x) {
        bool first = true, nan = false;
        T best{};
        for_each_below(src, sd, x, y, z, [&](T v) {
          if constexpr (std::is_floating_point_v<T>) nan = nan || std::isnan(v);
          if (first || (kMax ? v > best : v < best)) best = v;
          first = false;
        });
        if constexpr (std::is_floating_point_v<T>) {
          if (nan) best = std::numeric_limits<T>::quiet_NaN();
        }
        dst[(std::size_t(z) * std::size_t(dd.y) + std::size_t(y)) * std::size_t(dd.x) + std::size_t(x)] = best;
      }
    }
  }
}

// Interns sorted id sets: equal sets share one index.
class SetInterner {
 public:
  explicit SetInterner(LabelSetLevel& out) : out_(out) {}
  std::uint32_t intern(std::vector<std::uint32_t>& ids) {
    std::sort(ids.begin(), ids.end());
    ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
    if (last_ != kNone && ids == last_ids_) return last_;  // runs of one set are the common case
    std::string key(reinterpret_cast<const char*>(ids.data()), ids.size() * sizeof(std::uint32_t));
    auto [it, added] = index_.try_emplace(std::move(key), std::uint32_t(out_.offsets.size() - 1));
    if (added) {
      out_.ids.insert(out_.ids.end(), ids.begin(), ids.end());
      out_.offsets.push_back(std::uint32_t(out_.ids.size()));
    }
    last_ = it->second;
    last_ids_ = ids;
    return last_;
  }

 private:
  static constexpr std::uint32_t kNone = 0xFFFFFFFFu;
  LabelSetLevel& out_;
  std::unordered_map<std::string, std::uint32_t> index_;
  std::uint32_t last_ = kNone;
  std::vector<std::uint32_t> last_ids_;
};

// Level l + 1 sets from level-l voxels, `gather` appending the ids below one level-l voxel. Each
// output plane is interned on its own, in parallel; then the planes' sets are merged into one table
// in z order and the voxels renumbered, so the result does not depend on the thread count.
template <class Gather>
LabelSetLevel reduce_sets(ivec3 sd, vec3 spacing, Gather&& gather) {
  LabelSetLevel out;
  VolumeDesc d;
  d.dims = (sd + 1) / 2;
  d.spacing = spacing * 2.0f;
  d.type = VoxelType::U32;
  out.sets = Volume(d, "label sets");
  std::uint32_t* dst = out.sets.as<std::uint32_t>();
  const std::size_t plane = std::size_t(d.dims.x) * std::size_t(d.dims.y);
  std::vector<LabelSetLevel> planes(std::size_t(d.dims.z));  // each plane's own sets
  parallel_for(0, d.dims.z, [&](int z0, int z1) {
    std::vector<std::uint32_t> ids;
    for (int z = z0; z < z1; ++z) {
      SetInterner local(planes[std::size_t(z)]);
      std::uint32_t* o = dst + std::size_t(z) * plane;
      for (int y = 0; y < d.dims.y; ++y) {
        for (int x = 0; x < d.dims.x; ++x) {
          ids.clear();
          for (int k = 2 * z; k < std::min(2 * z + 2, sd.z); ++k)
            for (int j = 2 * y; j < std::min(2 * y + 2, sd.y); ++j)
              for (int i = 2 * x; i < std::min(2 * x + 2, sd.x); ++i) gather(i, j, k, ids);
          *o++ = local.intern(ids);
        }
      }
    }
  });
  SetInterner global(out);
  std::vector<std::vector<std::uint32_t>> renumber(planes.size());
  std::vector<std::uint32_t> ids;
  for (std::size_t z = 0; z < planes.size(); ++z) {
    for (std::uint32_t i = 0; i + 1 < planes[z].offsets.size(); ++i) {
      const auto set = planes[z].set(i);
      ids.assign(set.begin(), set.end());
      renumber[z].push_back(global.intern(ids));
    }
  }
  parallel_for(0, d.dims.z, [&](int z0, int z1) {
    for (int z = z0; z < z1; ++z) {
      std::uint32_t* o = dst + std::size_t(z) * plane;
      for (std::size_t i = 0; i < plane; ++i) o[i] = renumber[std::size_t(z)][o[i]];
    }
  });
  return out;
}

}  // namespace

std::size_t LabelSetLevel::bytes() const {
  return sets.desc().byte_size() + (offsets.size() + ids.size()) * sizeof(std::uint32_t);
}

LabelSetLevel reduce_label_sets(const Volume& labels) {
  const VolumeView v = labels.view();
  return reduce_sets(labels.dims(), labels.desc().spacing, [&](int x, int y, int z, std::vector<std::uint32_t>& ids) {
    ids.push_back(v.label(x, y, z));
  });
}

LabelSetLevel reduce_label_sets(const LabelSetLevel& finer) {
  const std::uint32_t* sets = finer.sets.as<std::uint32_t>();
  const ivec3 sd = finer.sets.dims();
  return reduce_sets(sd, finer.sets.desc().spacing, [&](int x, int y, int z, std::vector<std::uint32_t>& ids) {
    const auto s = finer.set(sets[(std::size_t(z) * std::size_t(sd.y) + std::size_t(y)) * std::size_t(sd.x) + std::size_t(x)]);
    ids.insert(ids.end(), s.begin(), s.end());
  });
}

void reduce_min(VoxelType t, const std::byte* src, ivec3 sd, std::byte* dst, int z0, int z1) {
  dispatch_voxel(t, [&](auto tag) {
    using T = decltype(tag);
    bound_rows<false>(reinterpret_cast<const T*>(src), sd, reinterpret_cast<T*>(dst), z0, z1);
  });
}

void reduce_max(VoxelType t, const std::byte* src, ivec3 sd, std::byte* dst, int z0, int z1) {
  dispatch_voxel(t, [&](auto tag) {
    using T = decltype(tag);
    bound_rows<true>(reinterpret_cast<const T*>(src), sd, reinterpret_cast<T*>(dst), z0, z1);
  });
}

void reduce_mean(VoxelType t, const std::byte* src, ivec3 sd, std::byte* dst, int z0, int z1) {
  dispatch_voxel(t, [&](auto tag) {
    using T = decltype(tag);
    mean_rows(reinterpret_cast<const T*>(src), sd, reinterpret_cast<T*>(dst), z0, z1);
  });
}

void reduce_mode(VoxelType t, const std::byte* src, ivec3 sd, std::byte* dst, int z0, int z1) {
  dispatch_label(
      t,
      [&](auto tag) {
        using T = decltype(tag);
        mode_rows(reinterpret_cast<const T*>(src), sd, reinterpret_cast<T*>(dst), z0, z1);
      },
      [] { SL_CHECK(!"labels must be an integer type"); });
}

const char* pyramid_name(PyramidKind k) { return k == PyramidKind::Max ? "max" : "mean"; }

PyramidKind parse_pyramid_kind(const std::string& text, const std::string& what) {
  if (text == "mean") return PyramidKind::Mean;
  if (text == "max") return PyramidKind::Max;
  throw InputError(what, "must be mean or max, got '" + text + "'");
}

ReduceFn intensity_reduction(PyramidKind k) { return k == PyramidKind::Max ? reduce_max : reduce_mean; }

void brick_read_box(const BrickLayout& layout, BrickId id, ivec3& first, ivec3& dims) {
  const ivec3 d = layout.dims(id.level());
  const ivec3 lo = glm::max(layout.brick_origin(id) - kBrickApron, ivec3(0));
  const ivec3 hi = glm::min(layout.brick_origin(id) + layout.brick_size + kBrickApron, d - 1);
  first = lo;
  dims = hi - lo + 1;
}

void fill_brick(const BrickLayout& layout, BrickId id, const std::byte* src, ivec3 src_first, ivec3 src_dims,
                int elem, std::span<std::byte> out) {
  const int n = layout.stored_size();
  SL_CHECK(out.size() == std::size_t(layout.stored_voxels()) * std::size_t(elem));
  const ivec3 d = layout.dims(id.level());
  const ivec3 start = layout.brick_origin(id) - kBrickApron;
  int xs[128];  // clamped source x of each stored column (B + 2 <= 66)
  for (int s = 0; s < n; ++s) xs[s] = std::clamp(start.x + s, 0, d.x - 1) - src_first.x;
  // The stored columns whose source is contiguous form one run: clamping only repeats the ends.
  int run0 = 0, run1 = n - 1;
  while (run0 < n - 1 && xs[run0 + 1] == xs[run0]) ++run0;
  while (run1 > run0 && xs[run1 - 1] == xs[run1]) --run1;
  for (int s = 0; s < n; ++s) SL_CHECK(xs[s] >= 0 && xs[s] < src_dims.x);
  std::byte* o = out.data();
  for (int sz = 0; sz < n; ++sz) {
    const int z = std::clamp(start.z + sz, 0, d.z - 1) - src_first.z;
    SL_CHECK(z >= 0 && z < src_dims.z);
    for (int sy = 0; sy < n; ++sy) {
      const int y = std::clamp(start.y + sy, 0, d.y - 1) - src_first.y;
      SL_CHECK(y >= 0 && y < src_dims.y);
      const std::byte* row = src + (std::size_t(z) * std::size_t(src_dims.y) + std::size_t(y)) *
                                       std::size_t(src_dims.x) * std::size_t(elem);
      for (int s = 0; s < run0; ++s) std::memcpy(o + std::size_t(s) * elem, row + std::size_t(xs[s]) * elem, elem);
      std::memcpy(o + std::size_t(run0) * elem, row + std::size_t(xs[run0]) * elem, std::size_t(run1 - run0 + 1) * elem);
      for (int s = run1 + 1; s < n; ++s) std::memcpy(o + std::size_t(s) * elem, row + std::size_t(xs[s]) * elem, elem);
      o += std::size_t(n) * elem;
    }
  }
}

}  // namespace sl
