// The SSE x-lerp path of trilerp (core/recon/sampling.h) against its scalar twin, the path the CUDA kernels
// run (STYLE.md #15): bit for bit on random 8-bit, 16-bit and float data, lane by lane, and through the
// dense sampler (edge rows with dx = 0, clamped borders); tests/cache/slot_sampler_simd_test.cpp
// checks the brick-slot sampler.
#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include <bit>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "core/recon/sampling.h"
#include "core/scene/volume.h"
#include "tests/random_voxels.h"

namespace sl {
namespace {

using test::bits;
using test::grid_of;
using test::random_volume;
using test::random_voxel;
using test::voxel_type;
using test::Xorshift;

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
