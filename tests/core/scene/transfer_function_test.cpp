// Transfer function: the table, opacity correction, the O(1) max-opacity query, and its JSON.
#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include <cmath>
#include <limits>

#include "core/util/error.h"
#include "core/scene/transfer_function.h"
#include "tests/test_util.h"

namespace sl {
namespace {

TEST(TransferFunction, TableInterpolatesThePiecewiseLinearFunction) {
  TransferFunction tf({{10.0f, {0, 0, 0, 0}}, {20.0f, {1, 0.5f, 0, 0.8f}}, {100.0f, {1, 1, 1, 0.2f}}});
  const TransferFunctionView v = tf.view(1.0f);
  for (float x : {0.0f, 10.0f, 12.5f, 20.0f, 55.0f, 100.0f, 300.0f}) {
    const vec4 a = v.lookup(x), b = tf.evaluate(x);
    for (int c = 0; c < 4; ++c) EXPECT_NEAR(a[c], b[c], 2e-3f) << x;
  }
  EXPECT_EQ(tf.evaluate(5.0f), vec4(0.0f));       // clamped below
  EXPECT_EQ(tf.evaluate(500.0f), vec4(1, 1, 1, 0.2f));  // and above
}

TEST(TransferFunction, OpacityCorrection) {
  TransferFunction tf({{0.0f, {1, 1, 1, 0.3f}}, {1.0f, {1, 1, 1, 0.3f}}});
  EXPECT_NEAR(tf.view(0.5f).lookup(0.5f).w, 1.0f - std::pow(0.7f, 0.5f), 1e-6f);
  EXPECT_NEAR(tf.view(2.0f).lookup(0.5f).w, 1.0f - 0.49f, 1e-6f);
}

RC_GTEST_PROP(TransferFunctionProp, MaxOpacityBoundsEveryLookupInTheRange, ()) {
  const int n = *rc::gen::inRange(1, 8);
  std::vector<TfPoint> pts;
  float v = float(*rc::gen::inRange(-100, 100));
  for (int i = 0; i < n; ++i) {
    const float a = *rc::gen::element(0.0f, 0.0f, 0.1f, 0.5f, 1.0f);
    pts.push_back({v, {0.5f, 0.5f, 0.5f, a}});
    v += float(*rc::gen::inRange(0, 50));
  }
  TransferFunction tf(pts);
  const float lo = float(*rc::gen::inRange(-200, 400)) * 0.5f;
  const float hi = lo + float(*rc::gen::inRange(0, 200)) * 0.5f;
  const float m = tf.max_opacity(lo, hi);
  const TransferFunctionView view = tf.view(1.0f);
  for (int i = 0; i <= 64; ++i) {
    const float x = lo + (hi - lo) * float(i) / 64.0f;
    RC_ASSERT(view.lookup(x).w <= m + 1e-6f);
  }
  // Zero max opacity means every table lookup in the range, corrected for any step, is transparent:
  // what the caster reads (culling is conservative with respect to the table, not the exact function).
  if (m == 0.0f) {
    const TransferFunctionView corrected = tf.view(0.5f);
    for (int i = 0; i <= 64; ++i) RC_ASSERT(corrected.lookup(lo + (hi - lo) * float(i) / 64.0f).w == 0.0f);
  }
}

TEST(TransferFunction, JsonErrorsNameTheFile) {
  auto expect_error = [](const std::string& text, const std::string& phrase) {
    try {
      parse_transfer_function(text, "tf.json");
      ADD_FAILURE() << text;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("tf.json"), std::string::npos);
      EXPECT_NE(std::string(e.what()).find(phrase), std::string::npos) << e.what();
    }
  };
  expect_error("{\"points\":[", "malformed JSON");
  expect_error("{}", "points");
  expect_error("{\"points\":[]}", "no points");
  expect_error("{\"points\":[{\"value\":1}]}", "rgba");
  expect_error("{\"points\":[{\"value\":1,\"rgba\":[0,0,0,2]}]}", "[0, 1]");
  expect_error("{\"points\":[{\"value\":5,\"rgba\":[0,0,0,1]},{\"value\":1,\"rgba\":[0,0,0,1]}]}", "ascending");
  const TransferFunction tf = default_transfer_function(0, 255);
  const TransferFunction back = parse_transfer_function(transfer_function_to_json(tf), "x");
  EXPECT_EQ(back.points().size(), tf.points().size());
  EXPECT_NEAR(back.evaluate(150).w, tf.evaluate(150).w, 1e-6f);
}

TEST(TransferFunction, NonFiniteSamplesStayInsideTheTable) {
  // NaN reads the low end (entry 0, like -Inf); ±Inf read the ends; a constant function too (Inf * 0).
  const TransferFunction tf({{10.0f, vec4(0.0f)}, {20.0f, vec4(1.0f)}});
  const TransferFunctionView v = tf.view(1.0f);
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  EXPECT_EQ(v.coord(nan).i, 0);
  EXPECT_EQ(v.coord(nan).f, 0.0f);
  EXPECT_EQ(v.lookup(nan), v.lookup(10.0f));
  EXPECT_EQ(v.lookup(-inf), v.lookup(10.0f));
  EXPECT_EQ(v.lookup(inf), v.lookup(20.0f));
  const TransferFunction flat({{5.0f, vec4(0.5f)}});
  const TransferFunctionView fv = flat.view(1.0f);
  for (float x : {nan, inf, -inf}) {
    EXPECT_GE(fv.coord(x).i, 0);
    EXPECT_LE(fv.coord(x).i, fv.size - 2);
    EXPECT_EQ(fv.lookup(x), vec4(0.5f));
    EXPECT_EQ(flat.max_opacity(x, x), 0.5f);
  }
  // A NaN block bound means an unknown range: the whole table, so culling stays conservative.
  EXPECT_EQ(tf.max_opacity(nan, 11.0f), 1.0f);
  EXPECT_EQ(tf.max_opacity(nan, nan), 1.0f);
  EXPECT_EQ(tf.max_opacity(-inf, inf), 1.0f);
  EXPECT_EQ(tf.max_opacity(-inf, 10.0f), 0.0f);
}

TEST(TransferFunction, OverflowingNumberAndDirectoryNameTheFile) {
  try {
    parse_transfer_function("{\"points\":[{\"value\":1e999,\"rgba\":[0,0,0,1]}]}", "tf.json");
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("tf.json: malformed JSON"), std::string::npos) << e.what();
  }
  const std::string dir = test::scratch_dir().string();
  try {
    load_transfer_function(dir);
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), dir + ": is a directory");
  }
}

}  // namespace
}  // namespace sl
