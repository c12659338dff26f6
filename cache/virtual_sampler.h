// The out-of-core sampler: every sample is read through the page table and the brick cache
// (DESIGN.md §4). A sample at level l uses brick (l, ...) when resident, else the finest resident
// ancestor; the wanted brick is reported once per frame in the unified miss buffer when it is not
// resident, and always inside UNKNOWN segments (an occupancy miss: the host decides, paper §8.2).
// Plain data, SL_HOST_DEVICE: the CUDA caster compiles it unchanged.
#pragma once

#include <cstdint>

#include "cache/brick.h"
#include "cache/brick_cache.h"
#include "cache/miss_buffer.h"
#include "cache/page_table.h"
#include "core/config.h"
#include "core/raycast.h"

namespace sl {

template <class T, class L>
struct VirtualSampler {
  const BrickLayout* layout = nullptr;
  PageTableView page_table;
  BrickCacheView cache;
  MissBufferView misses;
  std::uint32_t frame = 0;
  bool has_labels = false;

  // Entry of the brick serving p: the wanted level if resident, else the finest resident ancestor.
  SL_HOST_DEVICE PageEntry locate(const vec3& p, const SampleContext& c, BrickId& id) const {
    id = layout->brick_at(c.level, p);
    PageEntry e = page_table.lookup(id);
    if (c.occupancy_unknown || e.state() == PageEntry::State::Unmapped) misses.insert(id);
    for (int l = c.level + 1; !e.is_resident() && e.state() == PageEntry::State::Unmapped && l < layout->levels; ++l) {
      id = layout->brick_at(l, p);
      e = page_table.lookup(id);
    }
    if (e.is_resident()) cache.touch(e.slot(), frame);
    return e;
  }

  SL_HOST_DEVICE float sample(const vec3& p, const SampleContext& c) const {
    BrickId id;
    const PageEntry e = locate(p, c, id);
    if (e.is_resident()) return cache.template sampler<T>(e.slot(), *layout, id).sample(p);
    if (e.state() == PageEntry::State::Constant) return e.constant_value(cache.voxel_type);
    return 0.0f;  // empty, or nothing resident yet: rendered as missing
  }

  SL_HOST_DEVICE std::uint32_t label_at(const vec3& p, const SampleContext& c) const {
    if (!has_labels) return 0u;
    BrickId id;
    const PageEntry e = locate(p, c, id);
    if (e.is_resident()) return cache.template label_sampler<L>(e.slot(), *layout, id).label_at(p);
    return 0u;
  }

  SL_HOST_DEVICE vec3 gradient(const vec3& p, const vec3& spacing, const SampleContext& c) const {
    const vec3 s = spacing * float(1 << c.level);
    const vec3 hx(s.x, 0, 0), hy(0, s.y, 0), hz(0, 0, s.z);
    return vec3((sample(p + hx, c) - sample(p - hx, c)) / (2.0f * s.x),
                (sample(p + hy, c) - sample(p - hy, c)) / (2.0f * s.y),
                (sample(p + hz, c) - sample(p - hz, c)) / (2.0f * s.z));
  }
};

}  // namespace sl
