// Camera paths: keyframes are hit exactly, motion is smooth, up vectors never flip, bad JSON is named.
#include <gtest/gtest.h>

#include "core/camera_path.h"
#include "core/error.h"

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
  for (const std::string& text : {deep, eye_deep, std::string("{\"keyframes\":[{\"eye\":[1e999,0,0],\"center\":[0,0,0]}]}")}) {
    try {
      parse_camera_path(text, "path.json");
      ADD_FAILURE();
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), "path.json");
    }
  }
}

}  // namespace
}  // namespace sl
