// The central-difference gradient: exact on a linear field, the order of operations the samplers had
// (so shaded images keep their bits), and what DenseGrid::gradient returns.
#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include <cstring>

#include "core/recon/gradient.h"
#include "core/recon/sampling.h"
#include "core/scene/volume.h"

namespace sl {
namespace {

bool same_bits(const vec3& a, const vec3& b) { return std::memcmp(&a, &b, sizeof(vec3)) == 0; }

TEST(Gradient, ExactOnALinearField) {
  const auto f = [](const vec3& q) { return 2.0f * q.x - 0.5f * q.y + 4.0f * q.z; };
  const vec3 g = central_difference_gradient(vec3(3.0f, 1.0f, 2.0f), vec3(1.0f, 0.5f, 2.0f), f);
  EXPECT_FLOAT_EQ(g.x, 2.0f);
  EXPECT_FLOAT_EQ(g.y, -0.5f);
  EXPECT_FLOAT_EQ(g.z, 4.0f);
}

RC_GTEST_PROP(Gradient, SameBitsAsTheFormulaItReplaced, ()) {
  const float a = *rc::gen::inRange(-1000, 1000) / 97.0f, b = *rc::gen::inRange(-1000, 1000) / 89.0f;
  const auto f = [&](const vec3& q) { return std::sin(a * q.x) + q.y * q.y * b - q.z / (1.0f + q.x * q.x); };
  const vec3 p(*rc::gen::inRange(-500, 500) / 7.0f, *rc::gen::inRange(-500, 500) / 11.0f,
               *rc::gen::inRange(-500, 500) / 13.0f);
  const vec3 h(*rc::gen::inRange(1, 400) / 100.0f, *rc::gen::inRange(1, 400) / 100.0f,
               *rc::gen::inRange(1, 400) / 100.0f);
  // The expression the dense and virtual samplers each spelled out before.
  const vec3 hx(h.x, 0, 0), hy(0, h.y, 0), hz(0, 0, h.z);
  const vec3 before((f(p + hx) - f(p - hx)) / (2.0f * h.x), (f(p + hy) - f(p - hy)) / (2.0f * h.y),
                    (f(p + hz) - f(p - hz)) / (2.0f * h.z));
  RC_ASSERT(same_bits(central_difference_gradient(p, h, f), before));
}

TEST(Gradient, DenseGridUsesOneVoxelSteps) {
  VolumeDesc d;
  d.dims = ivec3(8, 6, 5);
  d.spacing = vec3(1.0f, 0.5f, 2.0f);
  d.type = VoxelType::U8;
  Volume v(d);
  for (int z = 0; z < 5; ++z)
    for (int y = 0; y < 6; ++y)
      for (int x = 0; x < 8; ++x) v.set(x, y, z, float(x * 3 + y * 7 + z * 11));
  DenseGrid<std::uint8_t> g{v.as<std::uint8_t>(), d.dims, 1.0f / d.spacing};
  const vec3 p = (vec3(3.3f, 2.6f, 2.1f) + 0.5f) * d.spacing;
  const vec3 grad = g.gradient(p, d.spacing);
  EXPECT_TRUE(same_bits(grad, central_difference_gradient(p, d.spacing, [&](const vec3& q) { return g.sample(q); })));
  // Voxel values rise by 3, 7, 11 per voxel: per world unit that is divided by the spacing.
  EXPECT_FLOAT_EQ(grad.x, 3.0f / d.spacing.x);
  EXPECT_FLOAT_EQ(grad.y, 7.0f / d.spacing.y);
  EXPECT_FLOAT_EQ(grad.z, 11.0f / d.spacing.z);
}

}  // namespace
}  // namespace sl
