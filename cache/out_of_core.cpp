#include "cache/out_of_core.h"

#include <algorithm>
#include <cstdio>
#include <cmath>
#include <cstring>
#include <functional>

#include "core/occupancy/culling.h"
#include "core/util/error.h"
#include "core/util/printable.h"

namespace sl {

struct OutOfCoreRenderer::Cull {
  CullParams params;
};

namespace {

int log2_exact(int v) {
  int l = 0;
  while ((1 << l) < v) ++l;
  return l;
}

// What a frame looks at and how it samples: pressure measured for one view says nothing of another.
std::uint64_t view_key(const Camera& c, const RenderSettings& s, std::uint64_t cull) {
  std::uint64_t h = 1469598103934665603ull ^ cull;
  auto mix = [&h](const void* p, std::size_t n) {
    const auto* b = static_cast<const unsigned char*>(p);
    for (std::size_t i = 0; i < n; ++i) h = (h ^ b[i]) * 1099511628211ull;
  };
  const float f[] = {c.eye.x, c.eye.y, c.eye.z, c.center.x, c.center.y, c.center.z, c.up.x, c.up.y, c.up.z,
                     c.fov_deg, c.height, s.step};
  const int i[] = {int(c.projection), s.width, s.height};
  mix(f, sizeof f);
  mix(i, sizeof i);
  return h;
}

std::size_t default_metadata_capacity(const OutOfCoreSettings& settings, std::size_t slots, int block) {
  if (settings.metadata_blocks > 0) return settings.metadata_blocks;
  const std::size_t per = std::size_t(settings.brick / std::max(block, 1));
  return std::max<std::size_t>(16384, 4 * slots * per * per * per);
}

}  // namespace

OutOfCoreRenderer::OutOfCoreRenderer(std::shared_ptr<const VolumeSource> source, const OutOfCoreSettings& settings,
                                     int block, std::unique_ptr<CastDevice> device)
    : source_(std::move(source)),
      settings_(settings),
      layout_(BrickLayout::make(source_->desc(), settings.brick, source_->name())),
      block_(block),
      page_table_(layout_),
      cache_(layout_, source_->desc().type,
             source_->has_labels() ? std::optional<VoxelType>(source_->label_type()) : std::nullopt,
             settings.cache_mb),
      misses_(1u << 16),
      loader_(source_, layout_, settings.loader_threads, settings.retry),
      tree_(make_block_grid(source_->desc().dims, source_->desc().spacing, block), OccupancyClass::Unknown),
      metadata_(default_metadata_capacity(settings, cache_.slot_count(), block)),
      device_(device ? std::move(device) : std::make_unique<CpuCastDevice>()) {
  validate_block_size(block);
  if (block > settings.brick) throw InputError("--block", "the culling block must not exceed the brick size (--brick)");
  brick_depth_offset_ = log2_exact(settings.brick / block);
  if (settings.lod >= layout_.levels) {
    throw InputError("--lod", "level " + std::to_string(settings.lod) + " does not exist (the volume has " +
                                  std::to_string(layout_.levels) + " levels)");
  }
  device_memory_ = !device_->shares_host_memory();
  DeviceConfig dc;
  dc.layout = layout_;
  dc.voxel_type = source_->desc().type;
  dc.has_labels = source_->has_labels();
  dc.label_type = source_->has_labels() ? source_->label_type() : VoxelType::U32;
  dc.slot_count = cache_.slot_count();
  dc.miss_capacity = misses_.capacity();
  dc.page_table_geometry = page_table_.view();
  dc.page_table_geometry.directory = nullptr;
  dc.page_table_geometry.pool = nullptr;
  for (int l = 0; l < layout_.levels; ++l) {
    const PageTableLevel& L = dc.page_table_geometry.level[l];
    dc.directory_words = std::max<std::size_t>(
        dc.directory_words, std::size_t(L.directory_offset) + std::size_t(L.pages.x) * L.pages.y * L.pages.z);
  }
  device_->configure(dc);
}

void OutOfCoreRenderer::map(BrickId id, PageEntry e) {
  // With device memory the table logs the words it writes (entry, chunk pointers, directory), so the
  // device mirror receives only those.
  page_table_.set(id, e, device_memory_ ? &dirty_ : nullptr);
}

OutOfCoreRenderer::~OutOfCoreRenderer() = default;

// A node's metadata comes from the level whose culling blocks it matches, so the tree refines exactly
// as far as the level of detail the rays ask for.
RegionClass OutOfCoreRenderer::region(int level, ivec3 c, OccupancyClass cls) const {
  return RegionClass{tree_.levels() - level, c * (1 << level), cls};
}

void OutOfCoreRenderer::set_region(const RegionClass& r) { tree_.touch(tree_.set_region_class(r), frame_); }

RegionClass OutOfCoreRenderer::culled_region(std::uint64_t key, const BlockMetadata& m, const Cull& cull) const {
  BrickId id;
  id.bits = key;
  OccupancyClass cls = classify_block(m, cull.params);
  if (cls == OccupancyClass::Empty && opened_.count(key)) cls = OccupancyClass::NonEmpty;
  return region(id.level(), id.coord(), cls);
}

bool OutOfCoreRenderer::open_provisional(const Cull& cull, const LodParams& lod, const RayGenerator& gen) {
  if (provisional_.empty()) return false;
  const vec3 extent = source_->desc().extent();
  bool opened = false;
  for (auto it = provisional_.begin(); it != provisional_.end();) {
    BrickId id;
    id.bits = *it;
    if (classify_block(metadata_.peek(*it), cull.params) != OccupancyClass::Empty) {
      ++it;
      continue;
    }
    // The finest level any sample in the block's world box asks for: the one at its nearest point.
    const vec3 s = layout_.level_spacing(id.level()) * float(block_);
    const vec3 lo = glm::min(vec3(id.coord()) * s, extent), hi = glm::min(lo + s, extent);
    const float t = gen.orthographic ? 0.0f : glm::length(glm::clamp(gen.eye, lo, hi) - gen.eye);
    if (lod.level_at(t) >= id.level()) {
      ++it;
      continue;
    }
    opened_.insert(*it);
    apply_metadata(*it, metadata_.at(*it, frame_), cull);
    it = provisional_.erase(it);
    opened = true;
  }
  return opened;
}

void OutOfCoreRenderer::apply_metadata(std::uint64_t key, const BlockMetadata& m, const Cull& cull) {
  const RegionClass r = culled_region(key, m, cull);
  if (r.depth >= 0) set_region(r);  // (a level coarser than the tree's root has no node)
}

template <class Fn>
void OutOfCoreRenderer::for_each_culling_block(BrickId id, Fn&& fn) const {
  const int per = layout_.brick_size / block_;
  const ivec3 dims = layout_.dims(id.level());
  for (int z = 0; z < per; ++z)
    for (int y = 0; y < per; ++y)
      for (int x = 0; x < per; ++x) {
        const ivec3 c = id.coord() * per + ivec3(x, y, z);
        if (c.x * block_ >= dims.x || c.y * block_ >= dims.y || c.z * block_ >= dims.z) continue;  // outside
        fn(c);
      }
}

std::uint32_t OutOfCoreRenderer::node_for_brick(BrickId id) const {
  const int depth = std::max(0, tree_.levels() - id.level() - brick_depth_offset_);
  const BlockGrid& g = tree_.grid();
  // First level-0 block of the brick: brick origin (level voxels) * 2^level / block.
  const glm::i64vec3 v = glm::i64vec3(layout_.brick_origin(id)) * (std::int64_t(1) << id.level()) / std::int64_t(block_);
  return tree_.descend(glm::clamp(ivec3(v), ivec3(0), g.blocks - 1), depth);
}

// Metadata of the culling blocks a brick holds, at its level (DESIGN.md §3). Level 0 from the brick
// itself (the apron supplies the neighbours of the dilation). A coarser level from the source's
// bounds over every level-0 voxel below (DESIGN.md §4, "metadata is a min/max pyramid"): a coarse
// block's range covers the finer voxels under it, so a region culled EMPTY at a coarse level is EMPTY
// at every finer level and the tree never has to un-cull when the view zooms in.
void OutOfCoreRenderer::compute_metadata(const LoadedBrick& b, const Cull& cull, bool apply) {
  const int l = b.id.level();
  std::vector<ivec3> blocks;
  for_each_culling_block(b.id, [&](ivec3 c) { blocks.push_back(c); });
  std::vector<BlockMetadata> ms(blocks.size());
  const bool bounded = l > 0 && source_->bound_blocks(layout_, l, block_, blocks, ms);
  if (!bounded) {  // (coarse: provisional, see open_provisional)
    const ivec3 S(layout_.stored_size());
    const bool labels = source_->has_labels() && !b.labels.empty();
    const VolumeView iv{b.intensity.data(), S, vec3(1.0f), source_->desc().type};
    const VolumeView lv{labels ? b.labels.data() : nullptr, S, vec3(1.0f), source_->label_type()};
    const ivec3 first_stored = layout_.brick_origin(b.id) - kBrickApron;
    for (std::size_t i = 0; i < blocks.size(); ++i) {
      ms[i] = compute_block_metadata(iv, labels ? &lv : nullptr, first_stored, layout_.dims(l), blocks[i] * block_,
                                     block_);
    }
  }
  for (std::size_t i = 0; i < blocks.size(); ++i) {
    ++metadata_computed_this_frame_;
    const std::uint64_t key = BrickId::pack(l, blocks[i]).bits;
    if (l > 0 && !bounded && !opened_.count(key)) provisional_.insert(key);
    if (apply) apply_metadata(key, ms[i], cull);
    metadata_.put(key, std::move(ms[i]), frame_);
  }
}

void OutOfCoreRenderer::upload(const Cull& cull) {
  LoaderBatch batch = loader_.collect(settings_.upload_budget);
  for (const BrickFailure& f : batch.failures) {
    // Reported once per cause — one corrupt chunk under many bricks is one warning, not one per
    // brick (issue 15); a failed brick (permanent, or out of retries) is never requested again. It
    // stays unmapped: sampled from its finest resident ancestor, or as missing, and counted short
    // of complete, so a frame with lost data never claims completeness 1.
    if (reported_causes_.insert(f.cause).second) {
      std::fprintf(stderr, "sparseleap: warning: brick failed to load, rendered as missing: %s\n",
                   printable(f.reason).c_str());
    }
    metadata_pending_.erase(f.id.bits);
    prefetch_requested_.erase(f.id);
    // Its region's occupancy can never be known: call it NON_EMPTY (conservative; the data read as
    // missing), so rays stop reporting occupancy misses there and the view can converge.
    for_each_culling_block(f.id, [&](ivec3 c) { set_region(region(f.id.level(), c, OccupancyClass::NonEmpty)); });
  }
  for (LoadedBrick& b : batch.bricks) {
    const bool prefetched = prefetch_requested_.erase(b.id) > 0;
    if (metadata_pending_.erase(b.id.bits)) {
      compute_metadata(b, cull);
    } else if (prefetched) {
      // Chosen under a known NON_EMPTY region: its own metadata will refine the tree there, as a
      // frame's load of it would (resolve_misses, `refine`) — once a frame samples it. Refined now,
      // the tree would open UNKNOWN siblings in the view on screen, which converged without them.
      bool known = true;
      for_each_culling_block(b.id, [&](ivec3 c) { known = known && metadata_.contains(BrickId::pack(b.id.level(), c).bits); });
      if (!known) {
        compute_metadata(b, cull, /*apply=*/false);
        unapplied_.insert(b.id);
      }
    }
    if (!page_table_.get(b.id).is_resident()) {
      // Protects the bricks the last frame used: the view's working set is not evicted to make room
      // for another brick of the same view (that was the thrash and the stall of issue 14).
      if (auto a = cache_.allocate(b.id, frame_ - 1)) {
        if (a->evicted.valid()) {
          map(a->evicted, PageEntry::unmapped());
          prefetched_unused_.erase(a->evicted);
          unapplied_.erase(a->evicted);  // (its metadata stays cached)
        }
        if (prefetched) {
          // Stamped older than the last frame: the first room a frame's own load may take.
          cache_.view().touch(a->slot, frame_ >= 2 ? frame_ - 2 : 0);
          prefetched_unused_.insert(b.id);
          ++prefetched_this_frame_;
        }
        if (device_memory_) {
          // The device copies the brick (asynchronously); the host slot stays untouched (and, being
          // allocated for overwrite, uncommitted): the host only does the bookkeeping.
          BrickUpload u;
          u.slot = a->slot;
          u.id = b.id;
          u.voxels = b.intensity;
          if (cache_.has_labels() && !b.labels.empty()) u.labels = b.labels;
          uploads_.push_back(u);
          map(b.id, PageEntry::resident(a->slot));
          if (!prefetched) ++loads_this_frame_;
          staged_.push_back(std::move(b));
          continue;
        }
        auto vox = cache_.slot_voxels(a->slot);
        std::memcpy(vox.data(), b.intensity.data(), std::min(vox.size(), b.intensity.size()));
        if (cache_.has_labels() && !b.labels.empty()) {
          auto lab = cache_.slot_labels(a->slot);
          std::memcpy(lab.data(), b.labels.data(), std::min(lab.size(), b.labels.size()));
        }
        map(b.id, PageEntry::resident(a->slot));
        if (!prefetched) ++loads_this_frame_;
      }
      // else: every slot holds a brick the last frame used; the brick is requested again when there
      // is room (resolve_misses requests no more than room()).
    }
    loader_.recycle(std::move(b));
  }
  if (device_memory_) {
    device_->upload_bricks(uploads_);
    uploads_.clear();
    for (LoadedBrick& b : staged_) loader_.recycle(std::move(b));
    staged_.clear();
  }
}

// Paper §8.2: each missed brick means what the occupancy tree says of its region. Unknown → its
// metadata (from cache, or by loading the brick), then cull and grow; known non-empty and not
// resident → load; known empty → map it Empty. Unknown regions never load data for sampling alone.
OutOfCoreRenderer::Resolved OutOfCoreRenderer::resolve_misses(const Cull& cull) {
  const std::vector<BrickId> ids = misses_.drain();
  Resolved res;
  std::vector<BrickId> load, data;
  std::vector<bool> refine;  // per data load: its metadata refines a coarser NON_EMPTY leaf
  for (const BrickId id : ids) {
    if (loader_.failed(id)) continue;
    const std::uint32_t n = node_for_brick(id);
    const OccupancyNode& nd = tree_.node(n);
    const bool leaf = tree_.is_leaf(n);
    const bool unknown = leaf ? nd.cls == OccupancyClass::Unknown : nd.count[int(OccupancyClass::Unknown)] > 0;
    if (unknown) {
      // Cached metadata regrows a retired or re-culled region without touching the data.
      bool cached = true;
      std::vector<std::uint64_t> keys;
      for_each_culling_block(id, [&](ivec3 c) {
        keys.push_back(BrickId::pack(id.level(), c).bits);
        cached = cached && metadata_.contains(keys.back());
      });
      if (cached) {
        for (std::uint64_t key : keys) apply_metadata(key, metadata_.at(key, frame_), cull);
      } else if (metadata_pending_.insert(id.bits).second) {
        load.push_back(id);  // metadata loads are always made: culling needs them
      }
      continue;
    }
    const OccupancyClass cls = leaf ? nd.cls : conservative_class(nd.count);
    const PageEntry e = page_table_.get(id);
    if (cls == OccupancyClass::Empty) {
      if (!e.is_resident() && e.state() != PageEntry::State::Empty) {
        map(id, PageEntry::empty());
        empty_entries_.push_back(id);
        res.changed = true;
      }
    } else if (!e.is_resident()) {
      data.push_back(id);
      // A NON_EMPTY leaf coarser than this brick's culling blocks (known from a coarser level):
      // the brick's own metadata, computed when it arrives, refines the tree as far as the level of
      // detail the rays now ask for (zooming in regains empty-space skipping there).
      bool known = true;
      for_each_culling_block(id, [&](ivec3 c) { known = known && metadata_.contains(BrickId::pack(id.level(), c).bits); });
      refine.push_back(leaf && int(nd.depth) < tree_.levels() - id.level() && !known);
    }
  }
  // Data loads only as far as there is room: a brick loaded without a slot would be dropped and
  // requested again every frame (loader work for nothing, and no progress).
  res.loadable = data.size();
  const std::size_t n = std::min(data.size(), room());
  load.insert(load.end(), data.begin(), data.begin() + std::ptrdiff_t(n));
  for (std::size_t i = 0; i < n; ++i) {
    if (refine[i]) metadata_pending_.insert(data[i].bits);
  }
  for (const BrickId id : load) prefetch_requested_.erase(id);  // the loader promotes them
  res.requested = loader_.request(load);
  res.changed = res.changed || res.requested > 0;
  return res;
}

std::size_t OutOfCoreRenderer::room() const {
  // Slots neither used by the last cast nor filled this frame (those bricks are wanted now), less
  // the loads already on their way.
  const std::size_t taken = hits_last_ + loads_this_frame_ + loader_.pending();
  return cache_.slot_count() > taken ? cache_.slot_count() - taken : 0;
}

void OutOfCoreRenderer::adapt_pressure(const Resolved& r) {
  const std::size_t cap = cache_.slot_count();
  const std::size_t need = hits_last_ + r.loadable;
  if (need > cap && pressure_ == 0) need_footprint_ = std::max(need_footprint_, need);
  if (settings_.lod >= 0) return;  // a pinned level is never coarsened (render reports the shortfall)
  const int most = 4 * (layout_.levels - 1);
  if (need > cap) {
    overflow_at_ = std::max(overflow_at_, pressure_);
    // Bricks on screen scale about with the square of the footprint: a quarter octave per factor
    // 2^(1/2) of excess, at least one step.
    const double excess = std::log2(double(need) / double(cap));
    pressure_ = std::min(most, pressure_ + std::max(1, int(std::ceil(2.0 * excess))));
  } else if (pressure_ > 0 && pressure_ - 1 > overflow_at_ && !r.changed && r.loadable == 0 &&
             loader_.pending() == 0 && metadata_pending_.empty()) {
    --pressure_;  // settled with room to spare for a try: refine one step
  }
}

void OutOfCoreRenderer::recull(const Cull& cull) {
  // Transfer function or labels changed: rebuild the tree from the cached metadata, coarse before fine
  // (nothing is recomputed or reloaded), and forget Empty mappings made under the old culling.
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
    const RegionClass r = culled_region(key, *m, cull);
    if (r.depth >= 0) regions.push_back(r);
  }
  tree_.recull(regions, frame_);
  for (const BrickId id : empty_entries_) {
    if (page_table_.get(id).state() == PageEntry::State::Empty) map(id, PageEntry::unmapped());
  }
  empty_entries_.clear();
}

void OutOfCoreRenderer::touch_used_bricks() {
  for (std::uint32_t s = 0; s < cache_.slot_count(); ++s) {
    if (cache_.last_used(s) != frame_) continue;
    const BrickId id = cache_.brick_in(s);
    if (!id.valid()) continue;
    tree_.touch(node_for_brick(id), frame_);
    for_each_culling_block(id, [&](ivec3 c) { metadata_.touch(BrickId::pack(id.level(), c).bits, frame_); });
  }
}

std::size_t OutOfCoreRenderer::metadata_blocks_in(const Box3& box) const {
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

Frame OutOfCoreRenderer::render(const OutOfCoreScene& scene, const RenderSettings& s) {
  Timer total;
  ++frame_;
  if (s.method != SkipMethod::SparseLeap && s.method != SkipMethod::None) {
    throw InputError("--method", std::string("out-of-core rendering supports sparseleap and none, not ") +
                                     to_string(s.method));
  }
  if (s.block != block_) throw InputError("--block", "changed after the out-of-core renderer was created");
  if (s.filter != Filter::Linear && s.method != SkipMethod::None) {
    // The bricks' one-voxel apron bounds each block's metadata to the trilinear footprint.
    throw InputError("--filter", std::string("out of core, ") + to_string(s.filter) +
                                     " reconstruction runs with --method none only (the bricks' one-voxel apron "
                                     "cannot bound a B-spline's footprint for culling)");
  }
  const VolumeDesc& d = source_->desc();
  Frame frame = begin_frame(s);
  Stats& st = frame.stats;

  // Culling inputs; a change re-culls from cached metadata.
  Cull cull;
  cull.params.mode = s.mode;
  cull.params.tf = scene.tf;
  cull.params.iso = s.iso;
  cull.params.enabled = scene.enabled;
  const std::uint64_t key = cull_key(cull.params);
  Timer t;
  if (cull_valid_ && key != cull_key_) recull(cull);
  cull_key_ = key;
  cull_valid_ = true;

  const std::uint64_t evictions_before = cache_.evictions();
  loads_this_frame_ = 0;
  prefetched_this_frame_ = 0;
  metadata_computed_this_frame_ = 0;
  if (device_memory_) device_->begin_frame();  // last frame's uploads have landed
  const std::uint64_t vk = view_key(scene.camera, s, key);
  if (vk != view_key_) {
    view_key_ = vk;
    overflow_at_ = -1;  // a new view may fit where the last did not
    need_footprint_ = 0;
  }
  const std::size_t in_flight_before = loader_.pending();
  const bool waiting = in_flight_before > prefetch_requested_.size();  // the frame's own loads
  upload(cull);
  Resolved resolved = resolve_misses(cull);
  // Prefetched bricks the last frame sampled: their metadata now refines the tree.
  for (const BrickId id : apply_next_) {
    for_each_culling_block(id, [&](ivec3 cb) {
      const std::uint64_t k = BrickId::pack(id.level(), cb).bits;
      if (const BlockMetadata* m = metadata_.find(k, frame_)) apply_metadata(k, *m, cull);
    });
    resolved.changed = true;
  }
  apply_next_.clear();
  const int pressure_before = pressure_;
  adapt_pressure(resolved);

  const RayGenerator gen = make_ray_generator(scene.camera, s.width, s.height);
  // Level of detail and the frame's sample grid. One global grid per frame keeps every method's
  // samples identical (DESIGN.md §8); its spacing follows the finest level any sample can use this
  // frame (the level at the volume's nearest point), so a view of a whole terabyte volume does not
  // sample coarse bricks 2^l times more densely than their voxels.
  LodParams lod;
  lod.levels = layout_.levels;
  lod.pinned = settings_.lod;
  const float pixel = 2.0f * gen.half_h / float(s.height);
  if (gen.orthographic) {
    lod.pixel_size = pixel;
  } else {
    lod.pixel_angle = pixel;
  }
  lod.inv_voxel = settings_.lod_bias / d.min_spacing();
  const LodParams footprint = lod;
  if (pressure_ > 0) lod.inv_voxel *= std::exp2(float(pressure_) * 0.25f);
  const vec3 nearest = glm::clamp(gen.eye, vec3(0.0f), d.extent());
  const float nearest_t = gen.orthographic ? 0.0f : glm::length(nearest - gen.eye);
  const int finest = lod.level_at(nearest_t);
  const float step = s.step * float(1 << finest);

  // Before the tree is used: provisional EMPTY where this frame wants a finer level opens now.
  resolved.changed = open_provisional(cull, lod, gen) || resolved.changed;
  tree_.propagate();
  tree_.collapse_homogeneous();
  st.time_ms.metadata = t.ms();

  t = Timer();
  tree_.retire_unused(frame_, settings_.retire_frames);
  // Metadata beyond its capacity, least recently used first: a dropped block is UNKNOWN when next
  // needed (read again for it), so nothing may still refer to it as provisional or opened.
  for (const std::uint64_t k : metadata_.evict(frame_)) {
    provisional_.erase(k);
    opened_.erase(k);
  }
  st.time_ms.tree = t.ms();
  st.tree_nodes = tree_.node_count();
  st.tree_bytes = tree_.memory_bytes();
  st.metadata_blocks = metadata_.size();
  st.metadata_bytes = metadata_.memory_bytes();
  st.metadata_computed = metadata_computed_this_frame_;

  SkipInputs skip;
  skip.method = s.method;
  skip.clip = clip_;
  if (s.method == SkipMethod::SparseLeap) {
    pipeline_.geometry(tree_, st);
    // The short-gap threshold stays in level-0 steps: conservative for any coarser grid.
    skip.lists = pipeline_.lists(tree_, s.method, gen, s.gap_eps * s.step * d.min_spacing(), st);
  }

  const CastParams p = make_cast_params(s, d, *scene.tf, scene.enabled, source_->has_labels(), step, lod);

  misses_.clear();
  CastRequest request;
  request.params = p;
  request.gen = gen;
  request.vbox = Box3{vec3(0.0f), d.extent()};
  request.skip = skip;
  request.frame = frame_;
  request.host = VirtualMemoryView{&layout_, page_table_.view(), cache_.view(), misses_.view(), source_->has_labels(), {}};
  shortfall_.assign(SampleShortfall::kStripes * SampleShortfall::kStride, 0);
  request.host.shortfall.counters = shortfall_.data();
  request.host.shortfall.footprint = footprint;
  request.host.shortfall.eye = gen.eye;
  request.host.shortfall.pressured = pressure_ > 0;
  cast(request, frame);
  touch_used_bricks();

  CacheStats& c = st.cache;
  c.present = true;
  c.frame = frame_;
  c.resident_mb = cache_.resident_mb();
  for (std::uint32_t sl = 0; sl < cache_.slot_count(); ++sl) {
    if (cache_.last_used(sl) != frame_) continue;
    ++c.hits;
    const BrickId id = cache_.brick_in(sl);
    if (!prefetched_unused_.empty() && prefetched_unused_.erase(id)) {
      ++c.prefetch_hits;
      if (unapplied_.erase(id)) apply_next_.push_back(id);
    }
  }
  c.loads = loads_this_frame_;
  c.stall = waiting && c.loads == 0;
  c.prefetched = prefetched_this_frame_;
  c.evictions = cache_.evictions() - evictions_before;
  // The frame's own loads in flight; prefetches are not what the view waits for.
  const std::size_t in_flight = loader_.pending();
  c.pending = in_flight > prefetch_requested_.size() ? in_flight - prefetch_requested_.size() : 0;
  c.prefetch_pending = in_flight - c.pending;
  const LoaderCounts lc = loader_.counts();
  c.failed = lc.failed;
  c.bricks_retried = lc.bricks_retried;
  c.retries = lc.retries;
  c.recovered = lc.recovered;
  c.page_table_bytes = page_table_.memory_bytes();
  std::uint64_t incomplete = 0, coarsened = 0;
  for (std::uint32_t k = 0; k < SampleShortfall::kStripes; ++k) {
    incomplete += shortfall_[k * SampleShortfall::kStride];
    coarsened += shortfall_[k * SampleShortfall::kStride + 1];
  }
  const double samples = double(std::max<std::uint64_t>(st.samples, 1));
  c.completeness = 1.0 - std::min(1.0, double(incomplete) / samples);
  c.lod_coarsened = std::min(1.0, double(coarsened) / samples);
  // Failed bricks are missed every frame, but nothing will load them: not counted as misses.
  for (const BrickId id : misses_.drain()) {
    if (loader_.failed(id)) continue;
    ++c.misses;
    if (!page_table_.get(id).is_resident()) ++c.bricks_missing;
  }
  const double slot_mb = double(cache_.slot_bytes()) / double(1 << 20);
  c.cache_mb = double(cache_.slot_count()) * slot_mb;
  if (need_footprint_ > cache_.slot_count()) {
    c.working_set_mb = double(need_footprint_) * slot_mb;
    c.working_set_level = settings_.lod >= 0 ? settings_.lod : footprint.level_at(nearest_t);
  }
  hits_last_ = c.hits;
  // Converged: nothing in flight, and the misses are either gone or the same ones as last frame with
  // nothing left to do about them (bricks that do not fit at a pinned level, or failed).
  // A coarsened view is settled only once refining is no longer worth a try.
  const bool may_refine = settings_.lod < 0 && pressure_ > 0 && pressure_ - 1 > overflow_at_;
  const bool settled = !may_refine && (c.misses == 0 || (!resolved.changed && c.loads == 0 &&
                                                         c.misses == misses_last_ && pressure_ == pressure_before));
  misses_last_ = c.misses;
  converged_ = settled && c.pending == 0 && metadata_pending_.empty() && apply_next_.empty();
  if (!converged_) {
    converged_at_ = -1;
  } else if (converged_at_ < 0) {
    converged_at_ = int(frame_);
  }
  c.converged_at_frame = converged_at_;
  if (settings_.prefetch) prefetch(scene, s, lod, gen, c);

  pipeline_.finish_frame(frame, s, &tree_, gen, total);
  return frame;
}

// Casts on the device. With device memory: first the page-table words changed this frame (each once,
// with its current value), then the cast; the misses and slot usage it copies back go into the host's
// miss buffer and usage stamps, where resolve_misses / touch_used_bricks / LRU read them exactly as
// after a CPU cast.
void OutOfCoreRenderer::cast(const CastRequest& r, Frame& frame) {
  CastFeedback fb;
  if (!device_memory_) {
    device_->cast(r, frame, fb);
    return;
  }
  std::sort(dirty_.dir_index.begin(), dirty_.dir_index.end());
  dirty_.dir_index.erase(std::unique(dirty_.dir_index.begin(), dirty_.dir_index.end()), dirty_.dir_index.end());
  dirty_.dir_value.resize(dirty_.dir_index.size());
  for (std::size_t k = 0; k < dirty_.dir_index.size(); ++k) dirty_.dir_value[k] = page_table_.directory_word(dirty_.dir_index[k]);
  std::sort(dirty_.pool_index.begin(), dirty_.pool_index.end());
  dirty_.pool_index.erase(std::unique(dirty_.pool_index.begin(), dirty_.pool_index.end()), dirty_.pool_index.end());
  dirty_.pool_value.resize(dirty_.pool_index.size());
  for (std::size_t k = 0; k < dirty_.pool_index.size(); ++k) {
    dirty_.pool_value[k] = page_table_.pool_word(dirty_.pool_index[k]);
  }
  device_->sync_page_table(dirty_);
  dirty_.clear();
  device_->cast(r, frame, fb);
  const MissBufferView mv = misses_.view();
  for (const BrickId id : fb.misses) mv.insert(id);
  const BrickCacheView cv = cache_.view();
  for (const std::uint32_t slot : fb.used_slots) {
    if (slot < cache_.slot_count() && cache_.brick_in(slot).valid()) cv.touch(slot, r.frame);
  }
}

}  // namespace sl
