#include "cache/volume_source.h"

#include "cache/pyramid.h"
#include "core/config.h"
#include "core/error.h"
#include "core/parallel.h"

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

}  // namespace

void VolumeSource::check_request(const BrickLayout& layout, BrickId id, std::span<std::byte> out_intensity,
                                 std::span<std::byte> out_labels) const {
  SL_CHECK(layout.contains(id));
  SL_CHECK(layout.dims(0) == desc().dims);
  const std::size_t n = layout.stored_voxels();
  SL_CHECK(out_intensity.size() == n * std::size_t(voxel_size(desc().type)));
  SL_CHECK(out_labels.empty() || (has_labels() && out_labels.size() == n * std::size_t(voxel_size(label_type()))));
}

MemoryVolumeSource::MemoryVolumeSource(std::shared_ptr<const Volume> intensity, std::shared_ptr<const Volume> labels,
                                       std::string name)
    : intensity_(std::move(intensity)), labels_(std::move(labels)), name_(std::move(name)) {
  SL_CHECK(intensity_ && !intensity_->empty());
  if (labels_) {
    if (!is_integer(labels_->type())) throw InputError(name_, "labels must be an integer type, not f32");
    if (labels_->dims() != intensity_->dims()) throw InputError(name_, "label dims differ from the volume's");
  }
  levels_.resize(1);
  label_levels_.resize(1);
  ivec3 d = intensity_->dims();
  while (d.x > 1 || d.y > 1 || d.z > 1) {
    const std::size_t l = levels_.size();
    levels_.push_back(reduce_level(level(int(l) - 1), reduce_mean));
    if (labels_) label_levels_.push_back(reduce_level(*label_level(int(l) - 1), reduce_mode));
    d = levels_.back().dims();
  }
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
  const Volume& v = level(l);
  fill_brick(layout, id, v.data(), ivec3(0), v.dims(), voxel_size(v.type()), out_intensity);
  if (!out_labels.empty()) {
    const Volume& lv = *label_level(l);
    fill_brick(layout, id, lv.data(), ivec3(0), lv.dims(), voxel_size(lv.type()), out_labels);
  }
}

}  // namespace sl
