// Camera paths: keyframes are hit exactly, motion is smooth, up vectors never flip, bad JSON is named.
#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

#include "core/scene/camera_path.h"
#include "core/util/error.h"

namespace sl {
namespace {

TEST(CameraPath, PassesThroughKeyframesAndStaysSmooth) {
  CameraPath p = orbit_path(vec3(100, 80, 60), 16);
  ASSERT_EQ(p.frames, 16);
  for (int i = 0; i < 16; ++i) {
    const Camera c = p.at(i);
    EXPECT_NEAR(glm::length(c.eye - p.keyframes[i].eye), 0.0f, 1e-3f) << i;
    EXPECT_NEAR(glm::dot(c.up, glm::normalize(c.center - c.eye)), 0.0f, 1e-5f);  // orthogonal up
    EXPECT_GT(c.up.y, 0.5f);  // never flips
  }
  // Consecutive orbit frames are equally far from the centre (a circle).
  const float r0 = glm::length(p.at(0).eye - p.at(0).center), r5 = glm::length(p.at(5).eye - p.at(5).center);
  EXPECT_NEAR(r0, r5, 1e-2f * r0);
}

TEST(CameraPath, InterpolatesBetweenKeyframes) {
  const std::string text = R"({"frames": 5, "keyframes": [
      {"eye": [0, 0, 10], "center": [0, 0, 0], "up": [0, 1, 0], "fov_deg": 30},
      {"eye": [10, 0, 10], "center": [0, 0, 0], "up": [0, 1, 0], "fov_deg": 50}]})";
  const CameraPath p = parse_camera_path(text, "path.json");
  EXPECT_EQ(p.frames, 5);
  EXPECT_NEAR(p.at(0).eye.x, 0.0f, 1e-6f);
  EXPECT_NEAR(p.at(4).eye.x, 10.0f, 1e-5f);
  EXPECT_NEAR(p.at(2).fov_deg, 40.0f, 1e-4f);
  EXPECT_GT(p.at(1).eye.x, 0.0f);
  EXPECT_LT(p.at(1).eye.x, p.at(2).eye.x);
  const CameraPath back = parse_camera_path(camera_path_to_json(p), "x");
  EXPECT_EQ(back.keyframes.size(), 2u);
}

TEST(CameraPath, BadJsonNamesTheFile) {
  for (const char* text : {"{\"frames\": 3", "{\"frames\": 3}", "{\"keyframes\": []}",
                           "{\"frames\": 2.5, \"keyframes\": [{\"eye\":[0,0,1],\"center\":[0,0,0]}]}",
                           "{\"keyframes\": [{\"eye\":[0,0,1]}]}"}) {
    try {
      parse_camera_path(text, "path.json");
      ADD_FAILURE() << text;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("path.json"), std::string::npos) << e.what();
    }
  }
}

TEST(CameraPath, DeepNestingAndOverflowAreOneInputError) {
  // Keyframes are read from the parsed value, never re-serialised (which recursed once per level).
  const std::string deep = "{\"keyframes\":[" + std::string(100000, '[') + std::string(100000, ']') + "]}";
  const std::string eye_deep =
      "{\"keyframes\":[{\"eye\":" + std::string(100000, '[') + std::string(100000, ']') + ",\"center\":[0,0,0]}]}";
  for (const std::string& text : {deep, eye_deep, std::string("{\"keyframes\":[{\"eye\":[1e999,0,0],\"center\":[0,0,0]}]}"),
                                  // A finite double that is an infinite float (the camera_path fuzzer).
                                  std::string("{\"keyframes\":[{\"eye\":[0,0,-4],\"center\":[0,0,0],\"projection\":"
                                              "\"orthographic\",\"height\":5e60}]}")}) {
    try {
      parse_camera_path(text, "path.json");
      ADD_FAILURE();
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), "path.json");
    }
  }
}

// Issue 14's soak path: the distance to the centre swings between the default and `closest` times it
// `cycles` times while the eye goes round once; the zoom path approaches the centre monotonically.
TEST(CameraPath, OrbitZoomOscillatesAndZoomInApproaches) {
  const vec3 extent(300, 200, 100);
  const Camera start = default_camera(extent);
  const float d0 = glm::length(start.eye - start.center);
  const CameraPath oz = orbit_zoom_path(extent, 120, 3, 0.25f);
  ASSERT_EQ(oz.frames, 120);
  float lo = 1e30f, hi = 0.0f;
  int turns = 0;  // local minima of the distance
  std::vector<float> d;
  for (int i = 0; i < oz.frames; ++i) {
    const Camera c = oz.at(i);
    d.push_back(glm::length(c.eye - c.center));
    lo = std::min(lo, d.back());
    hi = std::max(hi, d.back());
    EXPECT_NEAR(glm::length(c.center - start.center), 0.0f, 1e-3f);
  }
  for (std::size_t i = 1; i + 1 < d.size(); ++i) turns += d[i] < d[i - 1] && d[i] <= d[i + 1] ? 1 : 0;
  EXPECT_NEAR(hi, d0, 1e-3f * d0);
  EXPECT_NEAR(lo, 0.25f * d0, 0.01f * d0);
  EXPECT_EQ(turns, 3);
  // It goes round: the eye's direction in the horizontal plane covers both sides of the centre.
  EXPECT_LT(glm::dot(oz.at(0).eye - start.center, oz.at(60).eye - start.center), 0.0f);

  const CameraPath z = zoom_in_path(extent, 30, 0.2f);
  float last = 1e30f;
  for (int i = 0; i < z.frames; ++i) {
    const Camera c = z.at(i);
    const float di = glm::length(c.eye - c.center);
    EXPECT_LT(di, last) << i;
    last = di;
    // Straight towards the centre along the default view direction.
    EXPECT_NEAR(glm::dot(glm::normalize(c.eye - c.center), glm::normalize(start.eye - start.center)), 1.0f, 1e-4f);
  }
  EXPECT_NEAR(glm::length(z.at(0).eye - z.at(0).center), d0, 1e-3f * d0);
  EXPECT_NEAR(last, 0.2f * d0, 1e-3f * d0);
}

TEST(CameraPath, ExtrapolatesTheNextView) {
  const CameraPath z = zoom_in_path(vec3(100), 10, 0.5f);
  const Camera next = extrapolate_camera(z.at(3), z.at(4));
  // A geometric zoom is close to linear over one step: the extrapolation lands near the next frame.
  const float step = glm::length(z.at(5).eye - z.at(4).eye);
  EXPECT_LT(glm::length(next.eye - z.at(5).eye), 0.2f * step);
  EXPECT_GT(glm::length(next.eye - z.at(4).eye), 0.5f * step);
  // No motion: the same view.
  const Camera same = extrapolate_camera(z.at(4), z.at(4));
  EXPECT_EQ(same.eye, z.at(4).eye);
}

}  // namespace
}  // namespace sl
