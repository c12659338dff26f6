// Volume sources (DESIGN.md "Data model"): whatever answers "give me brick (level, bx, by, bz)". Host
// side; the brick loader calls read_brick from its worker threads. Implementations: MemoryVolumeSource
// (a volume in memory, e.g. a loaded NRRD) here, ProceduralNeuritesSource in procedural_neurites.h.
#pragma once

#include <cstddef>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "cache/brick.h"
#include "cache/pyramid.h"
#include "core/occupancy/block_metadata.h"
#include "core/scene/volume.h"

namespace sl {

class VolumeSource {
 public:
  virtual ~VolumeSource() = default;

  // Level-0 dims, spacing and intensity voxel type.
  virtual const VolumeDesc& desc() const = 0;
  virtual bool has_labels() const = 0;
  virtual VoxelType label_type() const = 0;  // meaningful only when has_labels()
  // What errors name as their file: the path, or the procedural spec.
  virtual const std::string& name() const = 0;

  // Fills brick `id` of `layout` (which must describe desc()): (B + 2)³ voxels, x fastest, apron
  // included, apron voxels outside the level clamped to the edge (brick.h). out_intensity holds
  // stored_voxels() * voxel_size(desc().type) bytes; out_labels the same for label_type(), or is
  // empty to skip labels. Thread-safe. Throws InputError(name(), reason) on I/O or data problems.
  virtual void read_brick(const BrickLayout& layout, BrickId id, std::span<std::byte> out_intensity,
                          std::span<std::byte> out_labels) const = 0;

  // Culling bounds (DESIGN.md "Virtual memory", "metadata is a min/max pyramid"): out[i] = the metadata
  // of culling block blocks[i] of `level` >= 1 (edge `block` level voxels, dilated by one level voxel
  // as dilated_block does) over every level-0 voxel below it, so that a block EMPTY at a coarse level
  // is EMPTY at every finer one and zooming in never loses structure. Returns false when the source
  // cannot bound its coarse levels (a stored pyramid without bounds): the renderer then derives their
  // metadata from the level's own voxels and treats it as provisional. Thread-safe; throws as
  // read_brick.
  virtual bool bound_blocks(const BrickLayout& layout, int level, int block, std::span<const ivec3> blocks,
                            std::span<BlockMetadata> out) const;

  // read_brick, and for a brick of level >= 1 the bounds (as bound_blocks) of its culling blocks of
  // edge `block` (brick_culling_blocks order) into `bounds` — left empty when the source cannot bound
  // them. A source that synthesises or reads the level-0 voxels below the brick for both does it once
  // (the default calls the two). Thread-safe; throws as read_brick.
  virtual void read_brick_bounded(const BrickLayout& layout, BrickId id, std::span<std::byte> out_intensity,
                                  std::span<std::byte> out_labels, int block,
                                  std::vector<BlockMetadata>& bounds) const;

  // The intensity pyramid read_brick serves at levels >= 1 (pyramid.h), fixed at construction.
  virtual PyramidKind pyramid() const { return PyramidKind::Mean; }

 protected:
  // Shared argument checks for implementations (internal errors: SL_CHECK).
  void check_request(const BrickLayout& layout, BrickId id, std::span<std::byte> out_intensity,
                     std::span<std::byte> out_labels) const;
};

// A volume (plus optional aligned label volume) held in memory. The pyramid of 2x reductions
// (pyramid.h) is computed once, in parallel, at construction, down to 1³ so that any brick size
// works: it costs about 1/7 of the volume's memory again (1/8 + 1/64 + ...), and in exchange every
// read_brick is a plain clamped copy — cheap, trivially thread-safe, and coarse bricks never rescan
// the full-resolution data (computing level l lazily would reread 8^l voxels per voxel, per brick).
// Beside it, the bounds pyramid for culling (min and max per voxel, and the label set per voxel as
// an interned set index): about 2/7 of the intensity's memory and 4/7 byte per voxel for labels.
class MemoryVolumeSource final : public VolumeSource {
 public:
  // labels may be null. Throws InputError(name, ...) when labels are not an integer type or their
  // dims differ from the intensity volume's. Both pyramids are built either way (the max one is the
  // culling bound), `pyramid` picks the one read_brick serves.
  MemoryVolumeSource(std::shared_ptr<const Volume> intensity, std::shared_ptr<const Volume> labels = nullptr,
                     std::string name = "volume", PyramidKind pyramid = PyramidKind::Mean);

  const VolumeDesc& desc() const override { return intensity_->desc(); }
  bool has_labels() const override { return labels_ != nullptr; }
  VoxelType label_type() const override { return labels_ ? labels_->type() : VoxelType::U32; }
  const std::string& name() const override { return name_; }
  void read_brick(const BrickLayout& layout, BrickId id, std::span<std::byte> out_intensity,
                  std::span<std::byte> out_labels) const override;
  bool bound_blocks(const BrickLayout& layout, int level, int block, std::span<const ivec3> blocks,
                    std::span<BlockMetadata> out) const override;
  PyramidKind pyramid() const override { return pyramid_; }

  // Level-l data (level 0 is the input) of the mean pyramid and of the max pyramid, for tests and
  // metadata; levels() reaches 1³.
  int levels() const { return int(levels_.size()); }
  const Volume& level(int l) const { return l == 0 ? *intensity_ : levels_[std::size_t(l)]; }
  const Volume& max_level(int l) const { return l == 0 ? *intensity_ : max_levels_[std::size_t(l)]; }
  const Volume* label_level(int l) const {
    return !labels_ ? nullptr : l == 0 ? labels_.get() : &label_levels_[std::size_t(l)];
  }
  // Bytes held by levels >= 1 (the pyramid's extra cost) and by the bounds pyramid.
  std::size_t pyramid_bytes() const;
  std::size_t bounds_bytes() const;

 private:
  std::shared_ptr<const Volume> intensity_, labels_;
  std::string name_;
  PyramidKind pyramid_;
  std::vector<Volume> levels_, label_levels_;  // index 0 unused (the inputs are level 0)
  std::vector<Volume> min_levels_, max_levels_;  // bounds; index 0 unused
  std::vector<LabelSetLevel> label_sets_;        // index 0 unused
};

// The intensity of `source` without its labels: has_labels() false, bricks read without their label
// arrays and culling bounds without label lists. What a renderer that never reads labels (no labels
// mode, no enabled-label mask) is given, so that its cache slots hold intensity only: u32 labels
// beside u8 voxels are four fifths of a slot.
std::shared_ptr<const VolumeSource> without_labels(std::shared_ptr<const VolumeSource> source);

}  // namespace sl
