#include "cache/formats/chunked_levels.h"

#include <cstring>

#include "cache/pyramid.h"
#include "core/util/error.h"
#include "core/util/parallel.h"

namespace sl {

Volume read_chunked_level(const VolumeDesc& d, ivec3 c, const ReadBox& read, const std::string& origin,
                          bool skip_unreadable) {
  Volume v(d, origin);
  const int rows = (d.dims.z + c.z - 1) / c.z;
  const std::size_t elem = std::size_t(voxel_size(d.type));
  const std::size_t plane = std::size_t(d.dims.x) * std::size_t(d.dims.y) * elem;
  parallel_for(0, rows, [&](int i) {
    const int z0 = i * c.z, nz = std::min(c.z, d.dims.z - z0);
    if (!skip_unreadable) {
      read(ivec3(0, 0, z0), ivec3(d.dims.x, d.dims.y, nz), v.data() + std::size_t(z0) * plane);
      return;
    }
    std::vector<std::byte> box(std::size_t(c.x) * std::size_t(c.y) * std::size_t(c.z) * elem);
    for (int y0 = 0; y0 < d.dims.y; y0 += c.y) {
      for (int x0 = 0; x0 < d.dims.x; x0 += c.x) {
        const ivec3 n(std::min(c.x, d.dims.x - x0), std::min(c.y, d.dims.y - y0), nz);
        try {
          read(ivec3(x0, y0, z0), n, box.data());
        } catch (const InputError&) {
          continue;
        }
        for (int z = 0; z < n.z; ++z) {
          for (int y = 0; y < n.y; ++y) {
            std::memcpy(v.data() + v.view().index(x0, y0 + y, z0 + z) * elem,
                        box.data() + (std::size_t(z) * std::size_t(n.y) + std::size_t(y)) * std::size_t(n.x) * elem,
                        std::size_t(n.x) * elem);
          }
        }
      }
    }
  });
  return v;
}

void copy_clamped(const Volume& v, ivec3 first, ivec3 n, std::byte* dst) {
  const std::size_t elem = std::size_t(voxel_size(v.type()));
  const ivec3 d = v.dims();
  for (int z = 0; z < n.z; ++z) {
    for (int y = 0; y < n.y; ++y) {
      for (int x = 0; x < n.x; ++x) {
        const ivec3 s = glm::min(first + ivec3(x, y, z), d - 1);
        std::memcpy(dst, v.data() + v.view().index(s.x, s.y, s.z) * elem, elem);
        dst += elem;
      }
    }
  }
}

std::vector<Volume> derive_levels(const Volume& base, ReduceFn reduce) {
  std::vector<Volume> out;
  const Volume* src = &base;
  while (src->dims().x > 1 || src->dims().y > 1 || src->dims().z > 1) {
    VolumeDesc d = src->desc();
    d.dims = (d.dims + 1) / 2;
    d.spacing *= 2.0f;
    Volume dst(d, "pyramid");
    parallel_for(0, d.dims.z, [&](int lo, int hi) {
      reduce(src->type(), src->data(), src->dims(), dst.data(), lo, hi);
    });
    out.push_back(std::move(dst));
    src = &out.back();
  }
  return out;
}

void read_chunked_brick(const BrickLayout& layout, BrickId id, int stored_levels, VoxelType type,
                        const ReadLevelBox& read, const std::vector<Volume>& derived, std::span<std::byte> out) {
  const int l = id.level();
  ivec3 first, n;
  brick_read_box(layout, id, first, n);
  const int elem = voxel_size(type);
  std::vector<std::byte> box(std::size_t(n.x) * std::size_t(n.y) * std::size_t(n.z) * std::size_t(elem));
  if (l < stored_levels) {
    read(l, first, n, box.data());
  } else {
    const std::size_t i = std::size_t(l - stored_levels);
    SL_CHECK(i < derived.size());  // derived levels reach 1³, and the layout never goes further
    copy_clamped(derived[i], first, n, box.data());
  }
  fill_brick(layout, id, box.data(), first, n, elem, out);
}

}  // namespace sl
