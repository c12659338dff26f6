#include "cache/volume_source.h"

#include <algorithm>

#include "cache/pyramid.h"
#include "core/util/config.h"
#include "core/util/error.h"
#include "core/util/parallel.h"

namespace sl {
namespace {

// Builds level l + 1 from level l with `reduce` (parallel over output slices; each output voxel is
// computed by one thread in a fixed order, so the result does not depend on scheduling).
template <class Reduce>
Volume reduce_level(const Volume& src, Reduce reduce) {
  VolumeDesc d = src.desc();
  d.dims = (d.dims + 1) / 2;
  d.spacing *= 2.0f;
  Volume dst(d, "pyramid");
  parallel_for(0, d.dims.z, [&](int lo, int hi) {
    reduce(src.type(), src.data(), src.dims(), dst.data(), lo, hi);
  });
  return dst;
}

bool is_integer(VoxelType t) { return t != VoxelType::F32; }

void drop_label_lists(std::span<BlockMetadata> ms) {
  for (BlockMetadata& m : ms) {
    m.has_labels = false;
    m.labels.clear();
    m.labels.shrink_to_fit();
  }
}

class WithoutLabels final : public VolumeSource {
 public:
  explicit WithoutLabels(std::shared_ptr<const VolumeSource> inner) : inner_(std::move(inner)) {}
  const VolumeDesc& desc() const override { return inner_->desc(); }
  bool has_labels() const override { return false; }
  VoxelType label_type() const override { return VoxelType::U32; }
  const std::string& name() const override { return inner_->name(); }
  void read_brick(const BrickLayout& layout, BrickId id, std::span<std::byte> out_intensity,
                  std::span<std::byte> out_labels) const override {
    SL_CHECK(out_labels.empty());
    inner_->read_brick(layout, id, out_intensity, {});
  }
  bool bound_blocks(const BrickLayout& layout, int level, int block, std::span<const ivec3> blocks,
                    std::span<BlockMetadata> out) const override {
    if (!inner_->bound_blocks(layout, level, block, blocks, out)) return false;
    drop_label_lists(out);
    return true;
  }
  void read_brick_bounded(const BrickLayout& layout, BrickId id, std::span<std::byte> out_intensity,
                          std::span<std::byte> out_labels, int block,
                          std::vector<BlockMetadata>& bounds) const override {
    SL_CHECK(out_labels.empty());
    inner_->read_brick_bounded(layout, id, out_intensity, {}, block, bounds);
    drop_label_lists(bounds);
  }
  PyramidKind pyramid() const override { return inner_->pyramid(); }

 private:
  std::shared_ptr<const VolumeSource> inner_;
};

}  // namespace

void VolumeSource::check_request(const BrickLayout& layout, BrickId id, std::span<std::byte> out_intensity,
                                 std::span<std::byte> out_labels) const {
  SL_CHECK(layout.contains(id));
  SL_CHECK(layout.dims(0) == desc().dims);
  const std::size_t n = layout.stored_voxels();
  SL_CHECK(out_intensity.size() == n * std::size_t(voxel_size(desc().type)));
  SL_CHECK(out_labels.empty() || (has_labels() && out_labels.size() == n * std::size_t(voxel_size(label_type()))));
}

bool VolumeSource::bound_blocks(const BrickLayout&, int, int, std::span<const ivec3>, std::span<BlockMetadata>) const {
  return false;
}

void VolumeSource::read_brick_bounded(const BrickLayout& layout, BrickId id, std::span<std::byte> out_intensity,
                                      std::span<std::byte> out_labels, int block,
                                      std::vector<BlockMetadata>& bounds) const {
  read_brick(layout, id, out_intensity, out_labels);
  bounds.clear();
  if (id.level() == 0) return;
  const std::vector<ivec3> blocks = brick_culling_blocks(layout, id, block);
  bounds.resize(blocks.size());
  if (!bound_blocks(layout, id.level(), block, blocks, bounds)) bounds.clear();
}

MemoryVolumeSource::MemoryVolumeSource(std::shared_ptr<const Volume> intensity, std::shared_ptr<const Volume> labels,
                                       std::string name, PyramidKind pyramid)
    : intensity_(std::move(intensity)), labels_(std::move(labels)), name_(std::move(name)), pyramid_(pyramid) {
  SL_CHECK(intensity_ && !intensity_->empty());
  if (labels_) {
    if (!is_integer(labels_->type())) throw InputError(name_, "labels must be an integer type, not f32");
    if (labels_->dims() != intensity_->dims()) throw InputError(name_, "label dims differ from the volume's");
  }
  levels_.resize(1);
  label_levels_.resize(1);
  min_levels_.resize(1);
  max_levels_.resize(1);
  label_sets_.resize(1);
  ivec3 d = intensity_->dims();
  while (d.x > 1 || d.y > 1 || d.z > 1) {
    const std::size_t l = levels_.size();
    levels_.push_back(reduce_level(level(int(l) - 1), reduce_mean));
    min_levels_.push_back(reduce_level(l == 1 ? *intensity_ : min_levels_[l - 1], reduce_min));
    max_levels_.push_back(reduce_level(l == 1 ? *intensity_ : max_levels_[l - 1], reduce_max));
    if (labels_) {
      label_levels_.push_back(reduce_level(*label_level(int(l) - 1), reduce_mode));
      label_sets_.push_back(l == 1 ? reduce_label_sets(*labels_) : reduce_label_sets(label_sets_[l - 1]));
    }
    d = levels_.back().dims();
  }
}

std::size_t MemoryVolumeSource::bounds_bytes() const {
  std::size_t n = 0;
  for (std::size_t l = 1; l < min_levels_.size(); ++l) {
    n += min_levels_[l].desc().byte_size() + max_levels_[l].desc().byte_size();
  }
  for (std::size_t l = 1; l < label_sets_.size(); ++l) n += label_sets_[l].bytes();
  return n;
}

bool MemoryVolumeSource::bound_blocks(const BrickLayout& layout, int level, int block, std::span<const ivec3> blocks,
                                      std::span<BlockMetadata> out) const {
  SL_CHECK(level >= 1 && level < levels() && layout.dims(level) == levels_[std::size_t(level)].dims());
  SL_CHECK(blocks.size() == out.size());
  const std::size_t l = std::size_t(level);
  const VolumeView lo = min_levels_[l].view(), hi = max_levels_[l].view();
  const VolumeView sets = labels_ ? label_sets_[l].sets.view() : VolumeView{};
  for (std::size_t i = 0; i < blocks.size(); ++i) {
    ivec3 first, end;
    dilated_block(lo.dims, blocks[i] * block, block, first, end);
    BlockMetadata m = compute_box_metadata(lo, hi, labels_ ? &sets : nullptr, first, end);
    if (labels_) {  // the set indices present -> the union of their ids
      std::vector<std::uint32_t> ids;
      for (const std::uint32_t s : m.labels) {
        const auto set = label_sets_[l].set(s);
        ids.insert(ids.end(), set.begin(), set.end());
      }
      std::sort(ids.begin(), ids.end());
      ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
      m.labels = std::move(ids);
    }
    out[i] = std::move(m);
  }
  return true;
}

std::size_t MemoryVolumeSource::pyramid_bytes() const {
  std::size_t n = 0;
  for (std::size_t l = 1; l < levels_.size(); ++l) n += levels_[l].desc().byte_size();
  for (std::size_t l = 1; l < label_levels_.size(); ++l) n += label_levels_[l].desc().byte_size();
  return n;
}

void MemoryVolumeSource::read_brick(const BrickLayout& layout, BrickId id, std::span<std::byte> out_intensity,
                                    std::span<std::byte> out_labels) const {
  check_request(layout, id, out_intensity, out_labels);
  const int l = id.level();
  SL_CHECK(l < levels() && level(l).dims() == layout.dims(l));
  const Volume& v = pyramid_ == PyramidKind::Max ? max_level(l) : level(l);
  fill_brick(layout, id, v.data(), ivec3(0), v.dims(), voxel_size(v.type()), out_intensity);
  if (!out_labels.empty()) {
    const Volume& lv = *label_level(l);
    fill_brick(layout, id, lv.data(), ivec3(0), lv.dims(), voxel_size(lv.type()), out_labels);
  }
}

std::shared_ptr<const VolumeSource> without_labels(std::shared_ptr<const VolumeSource> source) {
  SL_CHECK(source);
  if (!source->has_labels()) return source;
  return std::make_shared<WithoutLabels>(std::move(source));
}

}  // namespace sl
