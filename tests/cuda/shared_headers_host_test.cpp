// The g++ half of the shared-header compile check (shared_headers_compile.cu is the nvcc half): the
// same file built by the host compiler, its per-pixel function run for every pixel and compared with
// the CPU renderer — the entry point the kernels use is the CPU's, bit for bit.
#include <gtest/gtest.h>

#include "core/scene/generate.h"
#include "core/frame/in_core_renderer.h"
#include "tests/cuda/shared_headers_compile.cu"

namespace sl {
namespace {

TEST(SharedHeaders, HostBuildOfTheKernelEntryMatchesTheInCoreRenderer) {
  const GeneratedVolume g = generate_volume("neurites", ivec3(40, 36, 32), 4);
  const TransferFunction tf = default_transfer_function(0, 255);
  Scene scene;
  scene.volume = &g.intensity;
  scene.tf = &tf;
  scene.camera = default_camera(g.intensity.desc().extent());
  RenderSettings s;
  s.width = 24;
  s.height = 20;
  s.method = SkipMethod::None;
  const Frame ref = InCoreRenderer().render(scene, s);
  LabelSet storage;
  DenseGrid<std::uint8_t> grid{g.intensity.as<std::uint8_t>(), g.intensity.dims(), 1.0f / g.intensity.desc().spacing};
  const RayCaster<DenseSampler<std::uint8_t, std::uint8_t>> caster{make_cast_params(scene, s, storage), {grid, {}}};
  const RayGenerator gen = make_ray_generator(scene.camera, s.width, s.height);
  const Box3 vbox{vec3(0.0f), g.intensity.desc().extent()};
  float alpha = 0.0f;
  for (int y = 0; y < s.height; ++y) {
    for (int x = 0; x < s.width; ++x) {
      std::uint32_t samples = 0;
      const float a = test::shared_headers_pixel(caster, gen, vbox, SkipInputs{}, x, y, samples);
      const std::size_t i = std::size_t(y) * s.width + x;
      EXPECT_EQ(a, ref.image.rgba[i].w) << x << "," << y;
      EXPECT_EQ(float(samples), ref.image.channels.at("samples")[i]);
      alpha += a;
    }
  }
  EXPECT_GT(alpha, 0.5f);
  EXPECT_EQ(test::shared_headers_list(gen.ray(s.width / 2, s.height / 2), vbox, MissBufferView{}), 2u);
}

}  // namespace
}  // namespace sl
