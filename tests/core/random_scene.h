// Fixtures of the caster's property tests (fine_occupancy_test.cpp, sample_batch_test.cpp): a seeded
// generator, and a random scene — a noisy blob of intensity (u8 or u16) with shells of labels around a
// random centre, a transfer function with a random cut and a random label subset.
#pragma once

#include <algorithm>
#include <cstdint>

#include "core/scene/labels.h"
#include "core/util/rng.h"
#include "core/scene/transfer_function.h"
#include "core/scene/volume.h"

namespace sl::test_scene {

// The seed RapidCheck draws gives one scene and one set of rays.
struct Rng {
  SplitMix64 g;
  explicit Rng(std::uint64_t seed) : g(seed) {}
  std::uint64_t next() { return g.next(); }
  float uni(float a, float b) { return a + (b - a) * float(g.uniform_double()); }
};

struct SceneShape {
  VoxelType type = VoxelType::U8;
  int min_dim = 5;                        // dims are min_dim + [0, 30) per axis
  float min_falloff = 10.0f;              // the blob's intensity falls by [min_falloff, 60) per voxel
};

struct RandomScene {
  VolumeDesc desc;
  Volume vol, lab;
  TransferFunction tf;
  LabelSet enabled{6};
  bool use_labels = false;

  explicit RandomScene(Rng& r, const SceneShape& shape = {}) {
    desc.dims = ivec3(int(shape.min_dim + r.next() % 30), int(shape.min_dim + r.next() % 30),
                      int(shape.min_dim + r.next() % 30));
    desc.spacing = vec3(r.uni(0.5f, 2.0f), r.uni(0.5f, 2.0f), r.uni(0.5f, 2.0f));
    desc.type = shape.type;
    vol = Volume(desc);
    VolumeDesc ld = desc;
    ld.type = VoxelType::U16;
    lab = Volume(ld);
    const float scale = shape.type == VoxelType::U16 ? 257.0f : 1.0f;
    const vec3 c(r.uni(0, float(desc.dims.x)), r.uni(0, float(desc.dims.y)), r.uni(0, float(desc.dims.z)));
    const float falloff = r.uni(shape.min_falloff, 60.0f);
    for (int z = 0; z < desc.dims.z; ++z)
      for (int y = 0; y < desc.dims.y; ++y)
        for (int x = 0; x < desc.dims.x; ++x) {
          const float d = glm::length(vec3(x, y, z) - c);
          vol.set(x, y, z, scale * (std::max(0.0f, 255.0f - falloff * d) + float(r.next() % 8)));
          lab.set(x, y, z, float(int(d / 3.0f) % 6));
        }
    const float cut = r.uni(0.0f, 250.0f) * scale;
    tf = TransferFunction({{0.0f, vec4(0.0f)}, {cut, vec4(0.0f)}, {cut + scale, vec4(0.9f, 0.6f, 0.3f, 0.4f)},
                           {255.0f * scale, vec4(1.0f)}});
    use_labels = r.next() % 2 == 0;
    for (std::uint32_t id = 1; id < 6; ++id) {
      if (r.next() % 2) enabled.enable(id);
    }
  }
};

}  // namespace sl::test_scene
