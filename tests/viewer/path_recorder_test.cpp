#include "apps/viewer/path_recorder.h"

#include <gtest/gtest.h>

#include "apps/viewer/orbit_controller.h"
#include "core/util/error.h"
#include "tests/test_util.h"

namespace sl::viewer {
namespace {

TEST(PathRecorder, KeyframesBecomeAPathThatParseCameraPathAccepts) {
  OrbitController orbit(default_camera(vec3(64.0f)));
  PathRecorder rec(10);
  EXPECT_TRUE(rec.add(orbit.camera()));
  orbit.orbit(80.0f, 10.0f);
  EXPECT_TRUE(rec.add(orbit.camera()));
  orbit.zoom(2.0f);
  EXPECT_TRUE(rec.add(orbit.camera()));
  const CameraPath p = parse_camera_path(rec.to_json(), "recorded");
  ASSERT_EQ(p.keyframes.size(), 3u);
  EXPECT_EQ(p.frames, 21);  // (3 - 1) * 10 + 1: the path passes every keyframe
  EXPECT_NEAR(glm::length(p.keyframes[2].eye - orbit.camera().eye), 0.0f, 1e-3f);
  EXPECT_NEAR(glm::length(p.at(20).eye - orbit.camera().eye), 0.0f, 1e-3f);
}

TEST(PathRecorder, RepeatedIdenticalKeyframesAreNotAdded) {
  const Camera c = default_camera(vec3(32.0f));
  PathRecorder rec;
  EXPECT_TRUE(rec.add(c));
  EXPECT_FALSE(rec.add(c));
  EXPECT_EQ(rec.size(), 1u);
  EXPECT_EQ(rec.path().frames, 1);
}

TEST(PathRecorder, TimerAddsAKeyframePerIntervalWhileTheViewChanges) {
  OrbitController orbit(default_camera(vec3(32.0f)));
  PathRecorder rec;
  EXPECT_FALSE(rec.tick(0.0, orbit.camera()));  // timer off
  rec.set_interval(0.5);
  EXPECT_TRUE(rec.tick(10.0, orbit.camera()));  // first tick records at once
  orbit.orbit(5.0f, 0.0f);
  EXPECT_FALSE(rec.tick(10.2, orbit.camera()));  // too soon
  EXPECT_TRUE(rec.tick(10.6, orbit.camera()));
  EXPECT_FALSE(rec.tick(11.2, orbit.camera()));  // interval passed, view unchanged
  EXPECT_EQ(rec.size(), 2u);
  rec.set_interval(0.0);
  orbit.orbit(5.0f, 0.0f);
  EXPECT_FALSE(rec.tick(20.0, orbit.camera()));
  rec.clear();
  EXPECT_EQ(rec.size(), 0u);
}

TEST(PathRecorder, SaveWritesAFileBenchCanLoadAndRefusesAnEmptyPath) {
  const auto dir = test::scratch_dir();
  PathRecorder rec(4);
  const std::string file = (dir / "path.json").string();
  EXPECT_THROW(rec.save(file), InputError);
  EXPECT_FALSE(std::filesystem::exists(file));
  OrbitController orbit(default_camera(vec3(48.0f, 32.0f, 16.0f)));
  rec.add(orbit.camera());
  orbit.orbit(-40.0f, 20.0f);
  rec.add(orbit.camera());
  rec.save(file);
  const CameraPath p = load_camera_path(file);
  EXPECT_EQ(p.keyframes.size(), 2u);
  EXPECT_EQ(p.frames, 5);
}

TEST(PathRecorder, RecordedPathReplaysInBench) {
  const auto dir = test::scratch_dir();
  OrbitController orbit(default_camera(vec3(24.0f)));
  PathRecorder rec(2);
  rec.add(orbit.camera());
  orbit.orbit(100.0f, 0.0f);
  rec.add(orbit.camera());
  const std::string file = (dir / "path.json").string();
  rec.save(file);
  const test::RunResult r = test::run_sparseleap("bench --backend cpu --volume builtin:neurites:24x24x24 --size 32x24 "
                                                 "--methods sparseleap --path " + file + " --csv " +
                                                 (dir / "bench.csv").string());
  EXPECT_EQ(r.exit_code, 0) << r.output;
  // The path has (2 - 1) * 2 + 1 = 3 frames: bench's rows name frames 0..2 and no more.
  const std::string csv = test::read_text(dir / "bench.csv");
  EXPECT_NE(csv.find("\nsparseleap,2,"), std::string::npos) << csv;
  EXPECT_EQ(csv.find("\nsparseleap,3,"), std::string::npos) << csv;
}

}  // namespace
}  // namespace sl::viewer
