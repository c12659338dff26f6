// Tight boxes out of core (DESIGN.md "Ray segment lists"): the in-core tighten_leaf_boxes
// (core/occupancy/occupancy_geometry.h) from the resident bricks' own voxel masks. A NON_EMPTY leaf box
// whose samples all take one level of detail L, and whose level-L bricks are resident with masks for
// the frame's culling inputs, shrinks to the trilinear cells of those masks that are set inside it, a
// quarter voxel to spare on each side; a box without any set cell becomes empty. Every sample the
// caster fetches there has its cell's bit set (VirtualSampler::sample_unless_clear, the CPU batch), so
// the lists built from the result take the same samples and give the same image, with shorter
// segments to walk. A box whose samples straddle levels, or whose bricks are not all resident, keeps
// its extent.
//
// An extent depends only on the data, the culling inputs and L, not on residency: it is remembered
// (bounded) and used after its bricks are evicted. A brick whose cells are all clear is then never
// read, so it is not wanted back.
#pragma once

#include <cstddef>
#include <cstdint>
#include <unordered_map>

#include "cache/brick.h"
#include "cache/brick_cache.h"
#include "cache/page_table.h"
#include "core/cast/raycast.h"
#include "core/occupancy/occupancy_geometry.h"
#include "core/occupancy/occupancy_tree.h"
#include "core/scene/camera.h"

namespace sl {

class TightBoxes {
 public:
  // Remembers at most `capacity` extents (then forgets them all and starts again).
  explicit TightBoxes(std::size_t capacity) : capacity_(capacity) {}

  // `g` (flattened: flatten_sparse_subtrees) with its NON_EMPTY effective leaves shrunk as above.
  // `mask_key`: the culling key the resident slots' masks were built for (a change forgets every
  // extent); `lod`: the frame's levels of detail for the rays of `gen`.
  OccupancyGeometry tighten(const OccupancyTree& tree, const OccupancyGeometry& g, const BrickLayout& layout,
                            const BrickCache& cache, const PageTable& page_table, std::uint64_t mask_key,
                            const LodParams& lod, const RayGenerator& gen);

  std::size_t remembered() const { return known_.size(); }
  // Of the last tighten(): NON_EMPTY leaves shrunk (or emptied), and those left as they were.
  std::size_t shrunk() const { return shrunk_; }
  std::size_t kept() const { return kept_; }

  // The level every sample inside `box` takes under `lod` for the rays of `gen` (t: distance from
  // the eye), or -1 where the box straddles a change of level.
  static int box_level(const Box3& box, const LodParams& lod, const RayGenerator& gen);

 private:
  struct Key {
    std::uint64_t lo = 0, hi = 0;
    bool operator==(const Key&) const = default;
  };
  struct KeyHash {
    std::size_t operator()(const Key& k) const {
      return std::size_t(k.lo * 0x9E3779B97F4A7C15ull ^ (k.hi + 0x632BE59BD9B4E019ull + (k.lo << 6) + (k.lo >> 2)));
    }
  };
  static Key key_of(const Box3& box, int level, const BrickLayout& layout);
  // The shrunk box from level `level`'s resident masks; false where a brick it needs is not resident
  // with a current mask.
  static bool shrink(const Box3& box, int level, const BrickLayout& layout, const BrickCache& cache,
                     const PageTable& page_table, std::uint64_t mask_key, Box3& out);

  std::size_t capacity_;
  std::uint64_t mask_key_ = 0;
  std::unordered_map<Key, Box3, KeyHash> known_;
  std::size_t shrunk_ = 0, kept_ = 0;
};

}  // namespace sl
