// SplitMix64: the reference sequence (Vigna's splitmix64.c), and the uniform helpers' ranges. The
// generators draw from it, so this sequence is what keeps every generated data set unchanged.
#include <gtest/gtest.h>

#include "core/util/rng.h"

namespace sl {
namespace {

TEST(SplitMix64, MatchesTheReferenceSequence) {
  SplitMix64 a(0);
  EXPECT_EQ(a.next(), 0xE220A8397B1DCDAFull);
  EXPECT_EQ(a.next(), 0x6E789E6AA1B965F4ull);
  EXPECT_EQ(a.next(), 0x06C45D188009454Full);
  SplitMix64 b(1234567);
  EXPECT_EQ(b.next(), 0x599ED017FB08FC85ull);
  EXPECT_EQ(b.next(), 0x2C73F08458540FA5ull);
  EXPECT_EQ(b.next(), 0x883EBCE5A3F27C77ull);
}

TEST(SplitMix64, PureFunctionIsTheFirstOutput) {
  static_assert(splitmix64(0) == 0xE220A8397B1DCDAFull);
  for (std::uint64_t s : {0ull, 1ull, 42ull, ~0ull}) {
    SplitMix64 g(s);
    EXPECT_EQ(splitmix64(s), g.next());
    EXPECT_EQ(splitmix64_mix(s + kSplitMixGamma), splitmix64(s));
  }
}

TEST(SplitMix64, UniformsStayInTheirRanges) {
  SplitMix64 g(7);
  for (int i = 0; i < 10000; ++i) {
    const float u = g.uniform();
    EXPECT_GE(u, 0.0f);
    EXPECT_LT(u, 1.0f);
    const double d = g.uniform_double();
    EXPECT_GE(d, 0.0);
    EXPECT_LT(d, 1.0);
    const float ab = g.uniform(-2.0f, 3.0f);
    EXPECT_GE(ab, -2.0f);
    EXPECT_LE(ab, 3.0f);
    const vec3 b = g.in_ball();
    EXPECT_LE(glm::dot(b, b), 1.0f);
    EXPECT_NEAR(glm::length(g.unit()), 1.0f, 1e-5f);
  }
}

TEST(SplitMix64, UniformUsesTheTop24Bits) {
  SplitMix64 g(0), h(0);
  EXPECT_EQ(g.uniform(), float(h.next() >> 40) * 0x1p-24f);
  EXPECT_EQ(g.uniform_double(), double(h.next() >> 11) * 0x1.0p-53);
}

}  // namespace
}  // namespace sl
