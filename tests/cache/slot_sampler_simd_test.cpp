// The brick-slot sampler's SSE x-lerp path (cache/virtual_sampler.h over core/recon/sampling.h) against
// the scalar dense sampler over the same level, bit for bit (STYLE.md #15).
#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include <cstdint>
#include <optional>

#include "cache/brick_cache.h"
#include "cache/volume_source.h"
#include "core/recon/sampling.h"
#include "tests/random_voxels.h"

namespace sl {
namespace {

using test::bits;
using test::grid_of;
using test::random_volume;
using test::voxel_type;
using test::Xorshift;

// The brick-slot sampler (always dx = 1: the apron holds x1, or repeats the edge voxel) at any level,
// against the scalar dense sampler over that level: points anywhere in the brick's payload box,
// its faces included.
template <class T>
void check_slot() {
  const ivec3 dims(*rc::gen::inRange(1, 48), *rc::gen::inRange(1, 48), *rc::gen::inRange(1, 48));
  const vec3 spacing(*rc::gen::element(1.0f, 0.5f, 0.3f), *rc::gen::element(1.0f, 2.0f), 1.0f);
  Xorshift rng{*rc::gen::arbitrary<std::uint32_t>() | 1u};
  const MemoryVolumeSource src(random_volume(dims, spacing, voxel_type<T>(), rng, *rc::gen::element(0u, 1u, 2u)));
  const BrickLayout layout = BrickLayout::make(src.desc(), *rc::gen::element(8, 16));
  const int level = *rc::gen::inRange(0, layout.levels);
  const ivec3 nb = layout.bricks(level);
  const BrickId id =
      BrickId::pack(level, {*rc::gen::inRange(0, nb.x), *rc::gen::inRange(0, nb.y), *rc::gen::inRange(0, nb.z)});
  BrickCache cache(layout, voxel_type<T>(), std::nullopt, 1);
  const auto a = cache.allocate(id, 1);
  RC_ASSERT(a.has_value());
  src.read_brick(layout, id, cache.slot_voxels(a->slot), {});
  const SlotSampler<T> slot = cache.view().sampler<T>(a->slot, layout, id);
  const DenseGrid<T> dense = grid_of<T>(src.level(level), layout.level_spacing(level));
  const WorldBox box = layout.brick_box(id);
  const auto weight = [] {  // 0 and 1: the box's faces
    const int k = *rc::gen::inRange(0, 4);
    return k < 2 ? float(k) : float(*rc::gen::inRange(0, (1 << 16) + 1)) / float(1 << 16);
  };
  for (int i = 0; i < 64; ++i) {
    const vec3 p = box.lo + vec3(weight(), weight(), weight()) * (box.hi - box.lo);
    RC_ASSERT(bits(slot.sample(p)) == bits(dense.template sample<TrilerpPath::Scalar>(p)));
  }
}

RC_GTEST_PROP(SlotSamplerSimd, SampleEqualsScalarDenseU8, ()) { check_slot<std::uint8_t>(); }
RC_GTEST_PROP(SlotSamplerSimd, SampleEqualsScalarDenseU16, ()) { check_slot<std::uint16_t>(); }
RC_GTEST_PROP(SlotSamplerSimd, SampleEqualsScalarDenseF32, ()) { check_slot<float>(); }

}  // namespace
}  // namespace sl
