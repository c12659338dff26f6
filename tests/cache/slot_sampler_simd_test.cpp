// The brick-slot sampler's SSE x-lerp path (cache/virtual_sampler.h over core/recon/sampling.h) against
// the scalar dense sampler over the same level, bit for bit (STYLE.md #15).
#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include <cstdint>
#include <optional>

#include "cache/brick_cache.h"
#include "cache/volume_source.h"
#include "core/cast/sample_batch.h"
#include "core/scene/transfer_function.h"
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

// The CPU batch reading a brick's slot (core/cast/sample_batch.h, DvrBatchArgs::slot; the out-of-core
// caster's RayCaster::slot_run) against the slot sampler, bit for bit: along a random ray through the
// brick's payload box, under a random voxel mask, every lane of a batch whose voxels lie in the brick
// holds sample(p) and is fetched exactly where mask_visible(p) holds, and the mask scan queues exactly
// those samples, ascending.
template <class T>
void check_slot_batch() {
  if (!sample_batch_available()) return;
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
  RC_PRE(cache.masks_supported());
  const auto a = cache.allocate(id, 1);
  RC_ASSERT(a.has_value());
  src.read_brick(layout, id, cache.slot_voxels(a->slot), {});
  const std::span<std::uint64_t> mask = cache.slot_mask(a->slot);
  const std::uint32_t density = *rc::gen::element(0u, 1u, 4u, 8u);  // of 8: none, sparse, half, all
  for (std::uint64_t& w : mask) {
    w = 0;
    for (int b = 0; b < 64; ++b) w |= std::uint64_t(rng.next() % 8u < density) << b;
  }
  const SlotSampler<T> slot = cache.view().sampler<T>(a->slot, layout, id);
  const std::uint64_t* mbits = cache.view().slot_mask(a->slot);

  const float tf_max = sizeof(T) == 1 ? 255.0f : 65535.0f;
  const TransferFunction tf = default_transfer_function(0.0f, tf_max);
  const TransferFunctionView tv = tf.view(1.0f);
  const WorldBox box = layout.brick_box(id);
  const auto inside = [&] { return box.lo + vec3(float(rng.next() % 1000u), float(rng.next() % 1000u),
                                                 float(rng.next() % 1000u)) / 1000.0f * (box.hi - box.lo); };
  Ray ray;
  ray.origin = inside();
  const vec3 to = inside() - ray.origin;
  RC_PRE(glm::length(to) > 1e-3f);
  ray.dir = glm::normalize(to);
  const float dt = *rc::gen::element(0.05f, 0.25f, 0.5f, 1.0f) * layout.level_spacing(level).x;
  const int n_samples = int(glm::length(to) / dt);
  // Where sample k's voxel lies in the brick (the caster batches only such runs).
  const vec3 inv = layout.level_inv_spacing(level);
  const ivec3 lo = id.coord() * layout.brick_size, hi = lo + layout.brick_size, ld = layout.level_dims[level];
  const auto in_brick = [&](int k) {
    const vec3 u = ray.at(float(k) * dt) * inv;
    const ivec3 v = glm::clamp(ivec3(glm::floor(u)), ivec3(0), ld - 1);
    return glm::all(glm::greaterThanEqual(v, lo)) && glm::all(glm::lessThan(v, hi));
  };
  int end = 0;
  while (end < n_samples && in_brick(end)) ++end;

  DvrBatchArgs b;
  b.slot = true;
  b.data = slot.data;
  b.elem_size = int(sizeof(T));
  b.dims = ivec3(slot.stored);
  b.first = slot.first;
  b.inv_spacing = slot.inv_spacing;
  b.hi = vec3(slot.dims - 1);
  b.bytes = std::int64_t(slot.stored) * slot.stored * slot.stored * std::int64_t(sizeof(T));
  b.mask_bits = mbits;
  b.origin = ray.origin;
  b.dir = ray.dir;
  b.dt = dt;
  b.tf_table = &tv.table[0].x;
  b.tf_size = tv.size;
  b.tf_vmin = tv.vmin;
  b.tf_inv_step = tv.inv_step;
  RC_ASSERT(sample_batch_fits(b));
  std::vector<int> want;
  for (int k = 0; k < end; k += 8) {
    const int n = std::min(8, end - k);
    DvrBatchOut o;
    const int visible = dvr_batch(b, k, n, o);
    for (int j = 0; j < n; ++j) {
      const vec3 p = ray.at(float(k + j) * dt);
      const bool vis = slot.mask_visible(p, mbits);
      if (vis) want.push_back(k + j);
      if (visible < 0) continue;  // the slot's last bytes: the caller samples one by one
      RC_ASSERT(((visible >> j) & 1) == int(vis));
      if (!vis) continue;
      const float v = slot.sample(p);
      RC_ASSERT(bits(v) == bits(o.v[j]));
      const float alpha = tv.alpha_at(tv.coord(v));
      RC_ASSERT(bits(alpha) == bits(o.alpha[j]));
    }
  }
  // The scan, in chunks of at most 16 queued.
  std::vector<int> got;
  const SampleSpan span{0, end};
  int s = 0, k = 0;
  std::vector<int> queue(16 + 8);
  while (s < 1) {
    const int queued = dvr_mask_scan_spans(b, &span, 1, s, k, queue.data(), 0, 16);
    got.insert(got.end(), queue.begin(), queue.begin() + queued);
  }
  RC_ASSERT(got == want);
  RC_TAG(end == 0 ? "no sample in the brick" : density == 0 ? "empty mask" : "samples");
}

RC_GTEST_PROP(SlotSamplerSimd, SlotBatchEqualsTheSlotSamplerU8, ()) { check_slot_batch<std::uint8_t>(); }
RC_GTEST_PROP(SlotSamplerSimd, SlotBatchEqualsTheSlotSamplerU16, ()) { check_slot_batch<std::uint16_t>(); }

}  // namespace
}  // namespace sl
