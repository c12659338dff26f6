// The SSE x-lerp path of trilerp (core/sampling.h) against its scalar twin, the path the CUDA kernels
// run (STYLE.md #15): bit for bit on random 8-bit, 16-bit and float data, lane by lane, through the
// dense sampler (edge rows with dx = 0, clamped borders) and through the brick-slot sampler.
#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include <bit>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "cache/brick_cache.h"
#include "cache/volume_source.h"
#include "core/sampling.h"
#include "core/volume.h"

namespace sl {
namespace {

template <class T>
constexpr VoxelType voxel_type() {
  if constexpr (std::is_same_v<T, std::uint8_t>) return VoxelType::U8;
  if constexpr (std::is_same_v<T, std::uint16_t>) return VoxelType::U16;
  return VoxelType::F32;
}

std::uint32_t bits(float v) { return std::bit_cast<std::uint32_t>(v); }

// xorshift32 values: arbitrary but reproducible from a generated seed, so volumes of thousands of
// voxels need no per-voxel generator (and shrinking works on the seed and the shape).
struct Xorshift {
  std::uint32_t h;
  std::uint32_t next() {
    h ^= h << 13;
    h ^= h >> 17;
    h ^= h << 5;
    return h;
  }
};

// Voxel values drawn from `levels` distinct values (1: a uniform volume, which takes the SSE path's
// all-equal shortcut; small: many uniform 2x2x2 cells; 0: the type's whole range).
template <class T>
T random_voxel(Xorshift& rng, std::uint32_t levels) {
  const std::uint32_t r = rng.next();
  if constexpr (std::is_floating_point_v<T>) {
    return levels ? float(r % levels) : float(std::int32_t(r)) * 1.5e-4f;
  } else {
    return T(levels ? r % levels : r);
  }
}

// Interpolation weights: the exact ends 0 and 1 (and just inside them) as well as random fractions.
float random_weight() {
  switch (*rc::gen::inRange(0, 5)) {
    case 0: return 0.0f;
    case 1: return 1.0f;
    case 2: return *rc::gen::element(0.5f, 1e-7f, 0.99999994f);
    default: return float(*rc::gen::inRange(0, 1 << 24)) / float(1 << 24);
  }
}

template <class T>
void check_trilerp() {
  Xorshift rng{*rc::gen::arbitrary<std::uint32_t>() | 1u};
  const std::uint32_t levels = *rc::gen::element(0u, 1u, 2u, 3u);
  T rows[4][2];
  for (auto& row : rows)
    for (T& v : row) v = random_voxel<T>(rng, levels);
  const int dx = *rc::gen::inRange(0, 2);
  const float fx = random_weight(), fy = random_weight(), fz = random_weight();
  const float fast = trilerp(rows[0], rows[1], rows[2], rows[3], dx, fx, fy, fz);
  const float scalar = trilerp<TrilerpPath::Scalar>(rows[0], rows[1], rows[2], rows[3], dx, fx, fy, fz);
  RC_ASSERT(bits(fast) == bits(scalar));
}

RC_GTEST_PROP(TrilerpSimd, EqualsScalarU8, ()) { check_trilerp<std::uint8_t>(); }
RC_GTEST_PROP(TrilerpSimd, EqualsScalarU16, ()) { check_trilerp<std::uint16_t>(); }
RC_GTEST_PROP(TrilerpSimd, EqualsScalarF32, ()) { check_trilerp<float>(); }

// Each SSE lane on its own: with the other rows zero, weights fy, fz of 0 or 1 make the blend return
// exactly one lane's x-lerp (c0 + 1 * (c1 - 0) = c1 exactly), which must equal the scalar formula.
template <class T>
void check_lanes() {
  Xorshift rng{*rc::gen::arbitrary<std::uint32_t>() | 1u};
  const std::uint32_t levels = *rc::gen::element(0u, 2u);
  const T row[2] = {random_voxel<T>(rng, levels), random_voxel<T>(rng, levels)};
  const T zero[2] = {T(0), T(0)};
  const int dx = *rc::gen::inRange(0, 2);
  const float fx = random_weight();
  const float want = float(row[0]) + fx * (float(row[dx]) - float(row[0]));
  for (int lane = 0; lane < 4; ++lane) {
    const T* r[4] = {zero, zero, zero, zero};
    r[lane] = row;
    const float fy = float(lane & 1), fz = float(lane >> 1);
    const float fast = trilerp(r[0], r[1], r[2], r[3], dx, fx, fy, fz);
    const float scalar = trilerp<TrilerpPath::Scalar>(r[0], r[1], r[2], r[3], dx, fx, fy, fz);
    RC_ASSERT(bits(fast) == bits(want));
    RC_ASSERT(bits(scalar) == bits(want));
  }
}

RC_GTEST_PROP(TrilerpSimd, EachLaneIsTheScalarXLerpU8, ()) { check_lanes<std::uint8_t>(); }
RC_GTEST_PROP(TrilerpSimd, EachLaneIsTheScalarXLerpU16, ()) { check_lanes<std::uint16_t>(); }
RC_GTEST_PROP(TrilerpSimd, EachLaneIsTheScalarXLerpF32, ()) { check_lanes<float>(); }

std::shared_ptr<Volume> random_volume(ivec3 dims, vec3 spacing, VoxelType t, Xorshift& rng, std::uint32_t levels) {
  auto v = std::make_shared<Volume>(VolumeDesc{dims, spacing, t});
  const std::int64_t n = std::int64_t(dims.x) * dims.y * dims.z;
  for (std::int64_t i = 0; i < n; ++i) {
    switch (t) {
      case VoxelType::U8: v->as<std::uint8_t>()[i] = random_voxel<std::uint8_t>(rng, levels); break;
      case VoxelType::U16: v->as<std::uint16_t>()[i] = random_voxel<std::uint16_t>(rng, levels); break;
      default: v->as<float>()[i] = random_voxel<float>(rng, levels); break;
    }
  }
  return v;
}

template <class T>
DenseGrid<T> grid_of(const Volume& v, vec3 spacing) {
  return DenseGrid<T>{v.as<T>(), v.dims(), 1.0f / spacing};  // inv_spacing as the renderers build it
}

// A continuous voxel coordinate on one axis of n voxels: voxel centres, the first and last centre,
// the clamped borders outside the volume (and past the far face), or anywhere in between.
float random_voxel_coordinate(int n) {
  switch (*rc::gen::inRange(0, 6)) {
    case 0: return float(*rc::gen::inRange(0, n));
    case 1: return *rc::gen::element(0.0f, float(n - 1));
    case 2: return -float(*rc::gen::inRange(1, 300)) / 100.0f;
    case 3: return float(n - 1) + float(*rc::gen::inRange(1, 300)) / 100.0f;
    default: return float(*rc::gen::inRange(0, (n - 1) * 4096 + 1)) / 4096.0f;
  }
}

// Dense sampling over small odd volumes: rows whose last voxel repeats the edge (dx = 0), axes of one
// voxel, clamping outside the volume; every sample bit-identical through both paths.
template <class T>
void check_dense() {
  const ivec3 dims(*rc::gen::inRange(1, 24), *rc::gen::inRange(1, 24), *rc::gen::inRange(1, 24));
  const vec3 spacing(*rc::gen::element(1.0f, 0.5f, 0.3f), *rc::gen::element(1.0f, 2.0f, 0.7f),
                     *rc::gen::element(1.0f, 1.25f));
  Xorshift rng{*rc::gen::arbitrary<std::uint32_t>() | 1u};
  const auto vol = random_volume(dims, spacing, voxel_type<T>(), rng, *rc::gen::element(0u, 1u, 2u, 5u));
  const DenseGrid<T> g = grid_of<T>(*vol, spacing);
  for (int i = 0; i < 64; ++i) {
    const vec3 u(random_voxel_coordinate(dims.x), random_voxel_coordinate(dims.y), random_voxel_coordinate(dims.z));
    const vec3 p = (u + 0.5f) * spacing;
    RC_ASSERT(bits(g.sample(p)) == bits(g.template sample<TrilerpPath::Scalar>(p)));
  }
}

RC_GTEST_PROP(DenseGridSimd, SampleEqualsScalarU8, ()) { check_dense<std::uint8_t>(); }
RC_GTEST_PROP(DenseGridSimd, SampleEqualsScalarU16, ()) { check_dense<std::uint16_t>(); }
RC_GTEST_PROP(DenseGridSimd, SampleEqualsScalarF32, ()) { check_dense<float>(); }

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

// The SSE path is what these tests exercise: on an x86-64 build it must be compiled in.
TEST(TrilerpSimd, SsePathIsCompiledOnX86) {
#if defined(__x86_64__) && !defined(SL_NO_SSE)
  EXPECT_EQ(SL_SSE_TRILERP, 1);
#else
  EXPECT_EQ(SL_SSE_TRILERP, 0);
#endif
}

}  // namespace
}  // namespace sl
