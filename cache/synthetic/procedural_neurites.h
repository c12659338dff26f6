// Procedural neurites source: bricks of a virtual volume far larger than memory or disk (e.g.
// procedural:neurites:32768x32768x8192, about 8 TiB of u8) synthesised deterministically from their
// coordinates at any level (geometry in neurite_tubes.h). Level 0 looks like generate_volume's
// neurites: u8 intensity = tube brightness (120-255) times a smoothstep profile across 1.5 voxels
// around the tube surface, capped below 128 outside the core; u32 labels = the neurite id where the
// voxel centre is inside the tube (the deepest tube wins; ties to the larger id), so a voxel with
// intensity >= 128 is always labelled. Most voxels are zero.
//
// Coarse levels follow the same definition as MemoryVolumeSource (mean intensity, label mode), by
// methods chosen by level so that no brick has to walk more paths than a few hundred cells hold:
//  - Exact (levels 0-2): the brick's level-0 voxels are synthesised slab by slab and reduced 2x level
//    by level with pyramid.h: identical to MemoryVolumeSource's pyramid of the same level-0 data.
//  - PathSplat (levels 3-4): tube mass (brightness * cross-section * length) of every path sample,
//    deposited into the coarse voxel holding it and divided by the voxel's level-0 voxel count;
//    labels by the tube with the largest labelled volume in the voxel. Approximates the mean: it
//    ignores tube overlaps (max at level 0) and the u8 rounding of the intermediate levels.
//  - LineSplat (levels 5-6): as PathSplat, but each tube's mass is spread along a straight stand-in
//    segment derived from its hash (neurites::cell_tube_masses) instead of its walked path.
//  - CellSum (levels >= 7, voxels of >= kCell³): whole cells per voxel, each cell's mass from per-tube
//    hashes (neurites::cell_summary); past 2³ cells per voxel, a regular subset of 2³ scaled up.
// Fibres are sampled along their exact curves at every level (coarsely on the coarse ones). Mass is
// accumulated in 1/256 fixed point, so parallel accumulation is deterministic. The exact levels keep
// the walked paths of the cells they read lately (64 MiB, LRU): a cell lies under 64 level-0 bricks
// of 32³, and walking its paths is most of such a brick's synthesis.
//
// The max pyramid (PyramidKind::Max, pyramid.h) by the same methods: the exact levels reduce with
// reduce_max, so they equal MemoryVolumeSource's max pyramid; the splatted levels take, per voxel, the
// brightness of the brightest tube reaching it (a tube's core voxels have its brightness): on the
// PathSplat levels every voxel within a tube's radius of its walked centre line, on the coarser ones
// the voxels its stand-in segment or fibre samples fall in, on the CellSum levels over the same subset
// of cells as the mass. Like the splatted mean this approximates the reduction (halos, and on the
// hashed levels the stand-in's offset from the walked path), but no tube is lost: some voxel of every
// level gets its brightness.
//
// Culling bounds (bound_blocks, DESIGN.md "Virtual memory"): on the exact levels 1-2, from the level-0
// voxels below each block (synthesised as read_brick does; read_brick_bounded takes them from the
// very voxels the read synthesises, so a loaded coarse brick costs one synthesis, not two); on the splatted levels >= 3, whose voxels
// span 8+ level-0 voxels and whose blocks (128+ voxels across) all hold tubes, the whole u8 range
// without labels listed — conservative, and what those blocks' data would give anyway.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "cache/volume_source.h"

namespace sl {

class CellPathCache;

class ProceduralNeuritesSource final : public VolumeSource {
 public:
  enum class Method { Exact, PathSplat, LineSplat, CellSum };

  // Throws InputError(name, ...) when dims are not positive. `pyramid` picks the intensity of levels
  // >= 1 (labels are the same for both).
  ProceduralNeuritesSource(ivec3 dims, std::uint32_t seed = 1, std::string name = "procedural:neurites",
                           PyramidKind pyramid = PyramidKind::Mean);

  const VolumeDesc& desc() const override { return desc_; }
  bool has_labels() const override { return true; }
  VoxelType label_type() const override { return VoxelType::U32; }
  const std::string& name() const override { return name_; }
  void read_brick(const BrickLayout& layout, BrickId id, std::span<std::byte> out_intensity,
                  std::span<std::byte> out_labels) const override;
  bool bound_blocks(const BrickLayout& layout, int level, int block, std::span<const ivec3> blocks,
                    std::span<BlockMetadata> out) const override;
  void read_brick_bounded(const BrickLayout& layout, BrickId id, std::span<std::byte> out_intensity,
                          std::span<std::byte> out_labels, int block,
                          std::vector<BlockMetadata>& bounds) const override;
  PyramidKind pyramid() const override { return pyramid_; }

  std::uint32_t seed() const { return seed_; }
  static Method method(int level);

  // The level-l voxels [first, first + n) (clamped to the level by the caller), intensity u8 and
  // labels u32 (null: intensity only), x fastest; what read_brick copies from. Exposed for tests and
  // statistics.
  void synthesize(int level, ivec3 first, ivec3 n, std::uint8_t* intensity, std::uint32_t* labels) const;

 private:
  // read_brick; with `bounds`, read_brick_bounded on an exact level.
  void read(const BrickLayout& layout, BrickId id, std::span<std::byte> out_intensity, std::span<std::byte> out_labels,
            int block, std::vector<BlockMetadata>* bounds) const;

  VolumeDesc desc_;
  std::uint32_t seed_;
  std::string name_;
  PyramidKind pyramid_;
  // The walked paths of the cells the exact levels read lately (a 128³ cell lies under 64 level-0
  // bricks of 32³), bounded, shared by the threads.
  std::shared_ptr<CellPathCache> cell_paths_;
};

// "procedural:neurites:XxYxZ[:seed]" -> a ProceduralNeuritesSource. Throws InputError(spec, reason)
// for anything else or bad numbers.
std::unique_ptr<VolumeSource> parse_volume_spec(const std::string& spec, PyramidKind pyramid = PyramidKind::Mean);
// True when `spec` names a procedural source (starts with "procedural:"), not a file.
bool is_procedural_spec(const std::string& spec);

}  // namespace sl
