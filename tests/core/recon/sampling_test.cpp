// Trilinear sampling and ray generation by the conventions of DESIGN.md "Ray casting".
#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include "core/scene/camera.h"
#include "core/util/error.h"
#include "core/recon/sampling.h"
#include "core/scene/volume.h"

namespace sl {
namespace {

TEST(Sampling, TrilinearIsExactOnALinearField) {
  VolumeDesc d;
  d.dims = ivec3(9, 7, 5);
  d.spacing = vec3(1.0f, 0.5f, 2.0f);
  d.type = VoxelType::F32;
  Volume v(d);
  auto f = [](vec3 u) { return 2.0f * u.x - 3.0f * u.y + 0.5f * u.z + 1.0f; };  // u = voxel coordinate
  for (int z = 0; z < 5; ++z)
    for (int y = 0; y < 7; ++y)
      for (int x = 0; x < 9; ++x) v.set(x, y, z, f(vec3(x, y, z)));
  DenseGrid<float> g{v.as<float>(), d.dims, 1.0f / d.spacing};
  rc::check([&] {
    // Any point between the first and last voxel centres.
    const vec3 u(*rc::gen::inRange(0, 8000) / 1000.0f, *rc::gen::inRange(0, 6000) / 1000.0f,
                 *rc::gen::inRange(0, 4000) / 1000.0f);
    const vec3 world = (u + 0.5f) * d.spacing;
    RC_ASSERT(std::abs(g.sample(world) - f(u)) < 1e-4f);
  });
  // Voxel centres give the voxel values exactly; outside, the edge voxel (clamp).
  EXPECT_EQ(g.sample((vec3(3, 2, 1) + 0.5f) * d.spacing), f(vec3(3, 2, 1)));
  EXPECT_EQ(g.sample(vec3(-5.0f, 0.0f, 0.0f)), f(vec3(0, 0, 0)));
}

TEST(Sampling, LabelIsTheContainingVoxel) {
  VolumeDesc d;
  d.dims = ivec3(4, 4, 4);
  d.type = VoxelType::U16;
  Volume v(d);
  v.set(2, 1, 3, 77);
  DenseGrid<std::uint16_t> g{v.as<std::uint16_t>(), d.dims, vec3(1.0f)};
  EXPECT_EQ(g.label_at(vec3(2.01f, 1.99f, 3.5f)), 77u);
  EXPECT_EQ(g.label_at(vec3(1.99f, 1.5f, 3.5f)), 0u);
  EXPECT_EQ(g.label_at(vec3(2.5f, 1.5f, 4.0f)), 77u);  // on the far face: clamped into the volume
}

TEST(Camera, PerspectiveRaysPassThroughPixelCentres) {
  Camera c;
  c.eye = vec3(0, 0, 10);
  c.center = vec3(0, 0, 0);
  c.fov_deg = 90.0f;
  const RayGenerator g = make_ray_generator(c, 4, 2);
  // Pixel (0, 0) is top-left: direction has -x (left) and +y (up) components.
  const Ray r = g.ray(0, 0);
  EXPECT_LT(r.dir.x, 0.0f);
  EXPECT_GT(r.dir.y, 0.0f);
  EXPECT_NEAR(glm::length(r.dir), 1.0f, 1e-6f);
  // tan(45°) = 1: pixel centre y = 0.5 of 2 rows -> sy = 0.5; x = 0.5 of 4 -> sx = -0.75 * aspect 2.
  const vec3 expected = glm::normalize(vec3(-1.5f, 0.5f, -1.0f));
  EXPECT_NEAR(r.dir.x, expected.x, 1e-6f);
  EXPECT_NEAR(r.dir.y, expected.y, 1e-6f);
  EXPECT_NEAR(r.dir.z, expected.z, 1e-6f);
  EXPECT_EQ(r.origin, c.eye);
}

TEST(Camera, OrthographicRaysAreParallel) {
  Camera c;
  c.projection = Projection::Orthographic;
  c.eye = vec3(5, 5, 20);
  c.center = vec3(5, 5, 0);
  c.height = 10.0f;
  const RayGenerator g = make_ray_generator(c, 10, 10);
  const Ray a = g.ray(0, 0), b = g.ray(9, 9);
  EXPECT_EQ(a.dir, b.dir);
  EXPECT_NEAR(a.origin.x, 0.5f, 1e-5f);
  EXPECT_NEAR(a.origin.y, 9.5f, 1e-5f);
  EXPECT_NEAR(b.origin.x, 9.5f, 1e-5f);
}

TEST(Camera, JsonRoundTripAndErrors) {
  Camera c = default_camera(vec3(100, 80, 60));
  c.projection = Projection::Orthographic;
  const Camera d = parse_camera(camera_to_json(c), "x.json");
  EXPECT_NEAR(glm::length(d.eye - c.eye), 0.0f, 1e-3f);
  EXPECT_EQ(d.projection, Projection::Orthographic);
  auto expect_error = [](const std::string& text, const std::string& phrase) {
    try {
      parse_camera(text, "cam.json");
      ADD_FAILURE() << "no error for " << text;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("cam.json"), std::string::npos);
      EXPECT_NE(std::string(e.what()).find(phrase), std::string::npos) << e.what();
    }
  };
  expect_error("{\"eye\":[0,0,1],", "malformed JSON");
  expect_error("{\"center\":[0,0,0]}", "missing \"eye\"");
  expect_error("{\"eye\":[0,0,1],\"center\":[0,0]}", "array of 3");
  expect_error("{\"eye\":[1,1,1],\"center\":[1,1,1]}", "coincide");
  expect_error("{\"eye\":[0,1,0],\"center\":[0,0,0],\"up\":[0,1,0]}", "parallel");
  expect_error("{\"eye\":[0,0,1],\"center\":[0,0,0],\"fov_deg\":0}", "fov_deg");
  expect_error("{\"eye\":[0,0,1],\"center\":[0,0,0],\"projection\":\"fisheye\"}", "unknown projection");
  EXPECT_THROW(load_camera("/nonexistent/cam.json"), InputError);
}

TEST(Volume, AbsurdDimsAreRejected) {
  VolumeDesc d;
  d.dims = ivec3(2000000000, 2000000000, 2000000000);
  EXPECT_THROW(validate_desc(d, "big.nrrd"), InputError);
  d.dims = ivec3(0, 4, 4);
  EXPECT_THROW(validate_desc(d, "zero.nrrd"), InputError);
  d.dims = ivec3(4, 4, 4);
  d.spacing = vec3(1, -1, 1);
  EXPECT_THROW(validate_desc(d, "neg.nrrd"), InputError);
}

}  // namespace
}  // namespace sl
