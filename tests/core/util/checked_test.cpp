// The checked size arithmetic every reader uses on numbers from metadata: exact results when they fit,
// a SizeOverflow naming the quantity and its operands when they do not (never a wrapped value).
#include "core/util/checked.h"

#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include <cstdint>
#include <functional>
#include <limits>
#include <vector>

namespace sl {
namespace {

constexpr std::uint64_t kMax = std::numeric_limits<std::uint64_t>::max();

std::string overflow_text(const std::function<void()>& f) {
  try {
    f();
  } catch (const SizeOverflow& e) {
    return e.what();
  }
  return "(no overflow)";
}

TEST(Checked, ProductsThatFitAreExact) {
  EXPECT_EQ(checked_mul(1u << 31, 1u << 31, "x"), std::uint64_t(1) << 62);
  EXPECT_EQ(checked_add(kMax - 1, 1, "x"), kMax);
  EXPECT_EQ(checked_product({2, 3, 7}, "x"), 42u);
  EXPECT_EQ(checked_product({4, 4, 4}, "x", 2), 128u);
  EXPECT_EQ(checked_shl(1, 63, "x"), std::uint64_t(1) << 63);
  EXPECT_EQ(checked_shl(3, 62, "x"), std::uint64_t(3) << 62);
}

TEST(Checked, WrapsAreRefusedWithTheQuantityAndOperandsNamed) {
  EXPECT_EQ(overflow_text([] { checked_mul(std::uint64_t(1) << 40, std::uint64_t(1) << 30, "shard grid"); }),
            "shard grid (1099511627776 x 1073741824) overflows 64-bit arithmetic");
  EXPECT_EQ(overflow_text([] { checked_add(kMax, 1, "index bytes"); }),
            "index bytes (18446744073709551615 + 1) overflows 64-bit arithmetic");
  const std::vector<std::int64_t> five(5, std::int64_t(1) << 31);
  EXPECT_EQ(overflow_text([&] { checked_product(std::span<const std::int64_t>(five), "inner chunks per shard"); }),
            "inner chunks per shard (2147483648 x 2147483648 x 2147483648 x 2147483648 x 2147483648) overflows 64-bit "
            "arithmetic");
  // A product that wraps to exactly 0 (2^64) is an overflow, not an empty grid.
  EXPECT_NE(overflow_text([] { checked_product({std::int64_t(1) << 32, std::int64_t(1) << 32}, "grid"); }), "(no overflow)");
  EXPECT_NE(overflow_text([] { checked_product({std::int64_t(1), std::int64_t(-1)}, "grid"); }).find("negative"),
            std::string::npos);
  EXPECT_NE(overflow_text([] { checked_shl(1, 64, "index"); }), "(no overflow)");
  EXPECT_NE(overflow_text([] { checked_shl(5, 62, "index"); }), "(no overflow)");
  EXPECT_NE(overflow_text([] { checked_ceil_div(5, 0, "grid"); }).find("division by zero"), std::string::npos);
}

TEST(Checked, CeilDivisionNearTheTopDoesNotWrap) {
  EXPECT_EQ(checked_ceil_div(kMax, 1, "x"), kMax);
  EXPECT_EQ(checked_ceil_div(kMax, 2, "x"), (kMax / 2) + 1);
  EXPECT_EQ(checked_ceil_div(0, 7, "x"), 0u);
  EXPECT_EQ(checked_ceil_div(7, 7, "x"), 1u);
  EXPECT_EQ(checked_ceil_div(8, 7, "x"), 2u);
}

TEST(Checked, BoundsNameTheSizeAndTheBound) {
  EXPECT_EQ(checked_bound(64, 64, "index"), 64u);
  EXPECT_EQ(overflow_text([] { checked_bound(std::uint64_t(1) << 40, std::uint64_t(64) << 20, "shard index"); }),
            "shard index of 1099511627776 bytes (1048576 MiB) exceeds the 67108864 bytes (64 MiB) bound");
}

// For every pair: either the exact product (checked against 128-bit arithmetic) or a refusal exactly
// when the true product does not fit.
RC_GTEST_PROP(Checked, MulIsExactOrRefusedExactlyWhenItWraps, (std::uint64_t a, std::uint64_t b)) {
  const unsigned __int128 exact = (unsigned __int128)a * b;
  bool refused = false;
  std::uint64_t r = 0;
  try {
    r = checked_mul(a, b, "x");
  } catch (const SizeOverflow&) {
    refused = true;
  }
  RC_ASSERT(refused == (exact > kMax));
  if (!refused) RC_ASSERT((unsigned __int128)r == exact);
}

RC_GTEST_PROP(Checked, CeilDivIsTheRoundedUpQuotient, (std::uint64_t a, std::uint64_t b)) {
  RC_PRE(b > 0u);
  const unsigned __int128 exact = ((unsigned __int128)a + b - 1) / b;
  RC_ASSERT((unsigned __int128)checked_ceil_div(a, b, "x") == exact);
}

}  // namespace
}  // namespace sl
