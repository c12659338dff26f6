// The tile rasterizer of the CPU list builder (core/lists/segment_list_builder.cpp): one screen tile's lists,
// built in a per-thread scratch from the visibility order's entries that overlap the tile and copied
// into the frame's buffer. Its lanes (slab tests, lane masks) are eight pixels wide with AVX2 where the
// host has it, else four (SSE2), with a scalar twin (ListBuildPath). Host only; internal to the builder.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "core/lists/list_arena.h"
#include "core/lists/segment_list_builder.h"

namespace sl::detail {

inline constexpr int kListTile = kTileSize;  // the builder's tiles: kListTile x kListTile pixels

// An entry of the visibility order with all the tile loop reads of it, gathered once per frame in
// that order. A tile visits its entries in order, so it reads this array forward, where the boxes and
// their rectangles, indexed by box, were read at random (a cache miss an entry once the frame's
// working set outgrew the caches).
struct ListEntry {
  Box3 box;
  ScreenRect rect;
  std::uint32_t level;  // nesting level (nesting_levels)
  OccupancyClass cls, parent_cls;
  bool front;  // a FRONT entry, else a BACK one
  bool leaf;   // a FRONT entry whose box's BACK entry comes next (a leaf's, Alg. 3)
};
static_assert(sizeof(ListEntry) == 48, "ListEntry layout");

// What every tile of a frame shares.
struct ListTileJob {
  std::span<const ListEntry> entries;  // the visibility order's, indexed as it is
  const RayGenerator& gen;
  std::uint32_t depth;  // the deepest nesting level + 1
  float eps;
  EventArena& arena;
  SegmentListBuffer& out;
};

// The lists of every pixel of `tile` (its offset and count word in job.out, its events through
// job.arena; an empty list gets offset 0 and count 0), from the entries `entries` (indices into
// job.entries, in visibility order), counted into `st`. `path`: the lanes (Fast: eight with AVX2 where
// the host has it).
void build_list_tile(const ListTileJob& job, const ScreenRect& tile, const std::vector<std::uint32_t>& entries,
                     SegmentListStats& st, ListBuildPath path);

}  // namespace sl::detail
