#include "cache/out_of_core/lazy_occupancy.h"

#include <algorithm>
#include <utility>
#include <vector>

#include "core/util/error.h"

namespace sl {

namespace {

int log2_of_power_of_two(int v) {
  int l = 0;
  while ((1 << l) < v) ++l;
  return l;
}

}  // namespace

LazyOccupancy::LazyOccupancy(std::shared_ptr<const VolumeSource> source, const BrickLayout& layout, int block,
                             std::size_t metadata_capacity)
    : source_(std::move(source)),
      layout_(layout),
      block_(block),
      tree_(make_block_grid(source_->desc().dims, source_->desc().spacing, block), OccupancyClass::Unknown),
      metadata_(metadata_capacity) {
  if (block > layout_.brick_size) {
    throw InputError("--block", "the culling block must not exceed the brick size (--brick)");
  }
  brick_depth_offset_ = log2_of_power_of_two(layout_.brick_size / block);
}

bool LazyOccupancy::begin_frame(std::uint32_t frame, const CullParams& cull) {
  frame_ = frame;
  cull_ = cull;
  metadata_computed_this_frame_ = 0;
  const std::uint64_t key = sl::cull_key(cull);
  const bool changed = cull_valid_ && key != cull_key_;
  if (changed) recull();
  cull_key_ = key;
  cull_valid_ = true;
  return changed;
}

// Coarse before fine, so a finer block's class refines its coarser block's.
void LazyOccupancy::recull() {
  std::vector<std::pair<std::uint64_t, const BlockMetadata*>> entries;
  entries.reserve(metadata_.size());
  metadata_.for_each([&](std::uint64_t key, const BlockMetadata& m) { entries.emplace_back(key, &m); });
  std::sort(entries.begin(), entries.end(), [](const auto& a, const auto& b) {
    BrickId x, y;
    x.bits = a.first;
    y.bits = b.first;
    return x.level() != y.level() ? x.level() > y.level() : a.first < b.first;
  });
  std::vector<RegionClass> regions;
  regions.reserve(entries.size());
  for (const auto& [key, m] : entries) {
    const RegionClass r = culled_region(key, *m);
    if (r.depth >= 0) regions.push_back(r);
  }
  tree_.recull(regions, frame_);
}

// A node's metadata comes from the level whose culling blocks it matches, so the tree refines exactly
// as far as the level of detail the rays ask for.
RegionClass LazyOccupancy::region(int level, ivec3 c, OccupancyClass cls) const {
  return RegionClass{tree_.levels() - level, c * (1 << level), cls};
}

void LazyOccupancy::set_region(const RegionClass& r) { tree_.touch(tree_.set_region_class(r), frame_); }

RegionClass LazyOccupancy::culled_region(std::uint64_t key, const BlockMetadata& m) const {
  BrickId id;
  id.bits = key;
  OccupancyClass cls = classify_block(m, cull_);
  if (cls == OccupancyClass::Empty && opened_.count(key)) cls = OccupancyClass::NonEmpty;
  return region(id.level(), id.coord(), cls);
}

void LazyOccupancy::apply_metadata(std::uint64_t key, const BlockMetadata& m) {
  const RegionClass r = culled_region(key, m);
  if (r.depth >= 0) set_region(r);  // (a level coarser than the tree's root has no node)
}

template <class Fn>
void LazyOccupancy::for_each_culling_block(BrickId id, Fn&& fn) const {
  for (const ivec3 c : brick_culling_blocks(layout_, id, block_)) fn(c);
}

std::uint32_t LazyOccupancy::node_for_brick(BrickId id) const {
  const int depth = std::max(0, tree_.levels() - id.level() - brick_depth_offset_);
  const BlockGrid& g = tree_.grid();
  // First level-0 block of the brick: brick origin (level voxels) * 2^level / block.
  const glm::i64vec3 v = glm::i64vec3(layout_.brick_origin(id)) * (std::int64_t(1) << id.level()) / std::int64_t(block_);
  return tree_.descend(glm::clamp(ivec3(v), ivec3(0), g.blocks - 1), depth);
}

OccupancyClass LazyOccupancy::brick_class(BrickId id) const {
  const std::uint32_t n = node_for_brick(id);
  const OccupancyNode& nd = tree_.node(n);
  const bool leaf = tree_.is_leaf(n);
  const bool unknown = leaf ? nd.cls == OccupancyClass::Unknown : nd.count[int(OccupancyClass::Unknown)] > 0;
  if (unknown) return OccupancyClass::Unknown;
  return leaf ? nd.cls : conservative_class(nd.count);
}

bool LazyOccupancy::known_non_empty(BrickId id) const {
  const std::uint32_t n = node_for_brick(id);
  const OccupancyNode& node = tree_.node(n);
  const OccupancyClass cls = tree_.is_leaf(n) ? node.cls : conservative_class(node.count);
  return cls == OccupancyClass::NonEmpty && node.count[int(OccupancyClass::Unknown)] == 0;
}

bool LazyOccupancy::has_metadata(BrickId id) const {
  bool known = true;
  for_each_culling_block(id, [&](ivec3 c) { known = known && metadata_.contains(BrickId::pack(id.level(), c).bits); });
  return known;
}

bool LazyOccupancy::refined_by_loading(BrickId id) const {
  const std::uint32_t n = node_for_brick(id);
  return tree_.is_leaf(n) && int(tree_.node(n).depth) < tree_.levels() - id.level() && !has_metadata(id);
}

bool LazyOccupancy::apply_cached_metadata_if_complete(BrickId id) {
  if (!has_metadata(id)) return false;
  for_each_culling_block(id, [&](ivec3 c) {
    const std::uint64_t key = BrickId::pack(id.level(), c).bits;
    apply_metadata(key, metadata_.at(key, frame_));
  });
  return true;
}

void LazyOccupancy::apply_cached_metadata(BrickId id) {
  for_each_culling_block(id, [&](ivec3 c) {
    const std::uint64_t key = BrickId::pack(id.level(), c).bits;
    if (const BlockMetadata* m = metadata_.find(key, frame_)) apply_metadata(key, *m);
  });
}

bool LazyOccupancy::request_metadata(BrickId id) { return metadata_requested_.insert(id.bits).second; }

bool LazyOccupancy::take_metadata_request(BrickId id) { return metadata_requested_.erase(id.bits) > 0; }

// Metadata of the culling blocks a brick holds, at its level (DESIGN.md "Data model"). Level 0 from
// the brick itself (the apron supplies the neighbours of the dilation). A coarser level from the
// source's bounds over every level-0 voxel below (DESIGN.md "Virtual memory", "metadata is a min/max
// pyramid"): a coarse block's range covers the finer voxels under it, so a region culled EMPTY at a
// coarse level is EMPTY at every finer level and the tree never has to un-cull when the view zooms in.
LazyOccupancy::BrickMetadata LazyOccupancy::brick_metadata(const LoadedBrick& b) const {
  BrickMetadata m;
  m.blocks = brick_culling_blocks(layout_, b.id, block_);
  if (!b.bounds.empty()) {  // the loader read the source's bounds with the brick
    SL_CHECK(b.bounds.size() == m.blocks.size());
    m.metadata = b.bounds;
    m.bounded = true;
    return m;
  }
  m.metadata = block_metadata(b, m.blocks, m.bounded);
  return m;
}

void LazyOccupancy::compute_metadata(const LoadedBrick& b, bool apply, BrickMetadata* computed) {
  const int l = b.id.level();
  BrickMetadata here;
  if (computed == nullptr) {
    here = brick_metadata(b);
    computed = &here;
  }
  const std::vector<ivec3>& blocks = computed->blocks;
  std::vector<BlockMetadata>& ms = computed->metadata;
  const bool bounded = computed->bounded;
  for (std::size_t i = 0; i < blocks.size(); ++i) {
    ++metadata_computed_this_frame_;
    const std::uint64_t key = BrickId::pack(l, blocks[i]).bits;
    if (l > 0 && !bounded && !opened_.count(key)) provisional_.insert(key);
    if (apply) apply_metadata(key, ms[i]);
    metadata_.put(key, std::move(ms[i]), frame_);
  }
}

std::vector<BlockMetadata> LazyOccupancy::block_metadata(const LoadedBrick& b, const std::vector<ivec3>& blocks,
                                                         bool& bounded) const {
  const int l = b.id.level();
  std::vector<BlockMetadata> ms(blocks.size());
  bounded = l > 0 && source_->bound_blocks(layout_, l, block_, blocks, ms);
  if (bounded) return ms;
  // (coarse: provisional, see open_provisional)
  const ivec3 S(layout_.stored_size());
  const bool labels = source_->has_labels() && !b.labels.empty();
  const VolumeView iv{b.intensity.data(), S, vec3(1.0f), source_->desc().type};
  const VolumeView lv{labels ? b.labels.data() : nullptr, S, vec3(1.0f), source_->label_type()};
  const ivec3 first_stored = layout_.brick_origin(b.id) - kBrickApron;
  for (std::size_t i = 0; i < blocks.size(); ++i) {
    ms[i] = compute_block_metadata(iv, labels ? &lv : nullptr, first_stored, layout_.dims(l), blocks[i] * block_,
                                   block_);
  }
  return ms;
}

void LazyOccupancy::mark_unreadable(BrickId id) {
  metadata_requested_.erase(id.bits);
  for_each_culling_block(id, [&](ivec3 c) { set_region(region(id.level(), c, OccupancyClass::NonEmpty)); });
}

bool LazyOccupancy::update_tree(const LodParams& lod, const RayGenerator& gen) {
  const bool opened = open_provisional(lod, gen);
  tree_.propagate();
  tree_.collapse_homogeneous();
  return opened;
}

// Provisional coarse EMPTY (metadata a source could not bound) where this frame's level of detail
// wants a finer level: opened, i.e. NON_EMPTY from now on.
bool LazyOccupancy::open_provisional(const LodParams& lod, const RayGenerator& gen) {
  if (provisional_.empty()) return false;
  bool opened = false;
  for (auto it = provisional_.begin(); it != provisional_.end();) {
    BrickId id;
    id.bits = *it;
    if (classify_block(metadata_.peek(*it), cull_) != OccupancyClass::Empty || !wants_finer_level(id, lod, gen)) {
      ++it;
      continue;
    }
    opened_.insert(*it);
    apply_metadata(*it, metadata_.at(*it, frame_));
    it = provisional_.erase(it);
    opened = true;
  }
  return opened;
}

// The finest level any sample in the culling block's world box asks for: the one at its nearest point.
bool LazyOccupancy::wants_finer_level(BrickId block, const LodParams& lod, const RayGenerator& gen) const {
  const vec3 extent = source_->desc().extent();
  const vec3 s = layout_.level_spacing(block.level()) * float(block_);
  const vec3 lo = glm::min(vec3(block.coord()) * s, extent), hi = glm::min(lo + s, extent);
  const float t = gen.orthographic ? 0.0f : glm::length(glm::clamp(gen.eye, lo, hi) - gen.eye);
  return lod.level_at(t) < block.level();
}

void LazyOccupancy::retire(std::uint32_t retire_frames) {
  tree_.retire_unused(frame_, retire_frames);
  // Metadata beyond its capacity, least recently used first: a dropped block is UNKNOWN when next
  // needed (read again for it), so nothing may still refer to it as provisional or opened.
  for (const std::uint64_t k : metadata_.evict(frame_)) {
    provisional_.erase(k);
    opened_.erase(k);
  }
}

void LazyOccupancy::touch_brick(BrickId id) {
  tree_.touch(node_for_brick(id), frame_);
  for_each_culling_block(id, [&](ivec3 c) { metadata_.touch(BrickId::pack(id.level(), c).bits, frame_); });
}

void LazyOccupancy::fill_stats(Stats& st) const {
  st.tree_nodes = tree_.node_count();
  st.tree_bytes = tree_.memory_bytes();
  st.metadata_blocks = metadata_.size();
  st.metadata_bytes = metadata_.memory_bytes();
  st.metadata_computed = metadata_computed_this_frame_;
}

std::size_t LazyOccupancy::metadata_blocks_in(const Box3& box) const {
  std::size_t n = 0;
  metadata_.for_each([&](std::uint64_t key, const BlockMetadata&) {
    BrickId id;
    id.bits = key;
    const vec3 s = layout_.level_spacing(id.level()) * float(block_);
    const vec3 lo = vec3(id.coord()) * s, hi = lo + s;
    if (lo.x < box.hi.x && lo.y < box.hi.y && lo.z < box.hi.z && hi.x > box.lo.x && hi.y > box.lo.y &&
        hi.z > box.lo.z) {
      ++n;
    }
  });
  return n;
}

}  // namespace sl
