// Samplers the kernels cast over. They only dispatch to core/ and cache/ code (DenseGrid,
// VirtualSampler): the label type is chosen at run time instead of being a template parameter, which
// divides the kernel instantiations by three (build time; docs/cuda.md, "Building: architectures and compile time").
#pragma once

#include <cstdint>

#include "cache/virtual_sampler.h"
#include "core/recon/gradient.h"
#include "core/scene/voxel_dispatch.h"
#include "core/cast/raycast.h"
#include "core/recon/sampling.h"

namespace sl::cuda {

// In core: dense intensity of type VT; labels u8, u16 or u32 (at most one grid non-null).
template <class VT>
struct DenseAnyLabelSampler {
  DenseGrid<VT> volume;
  DenseGrid<std::uint8_t> l8;
  DenseGrid<std::uint16_t> l16;
  DenseGrid<std::uint32_t> l32;

  SL_HOST_DEVICE float sample(const vec3& p, const SampleContext&) const { return volume.sample(p); }
  SL_HOST_DEVICE float voxel(const ivec3& v, const SampleContext&) const { return volume.voxel_clamped(v); }  // exact iso
  SL_HOST_DEVICE std::uint32_t label_at(const vec3& p, const SampleContext&) const {
    if (l8.data) return l8.label_at(p);
    if (l16.data) return l16.label_at(p);
    if (l32.data) return l32.label_at(p);
    return 0u;
  }
  SL_HOST_DEVICE vec3 gradient(const vec3& p, const vec3& spacing, const SampleContext&) const {
    return volume.gradient(p, spacing);
  }
};

// Out of core, software trilinear from the linear slot pool (cache/virtual_sampler.h unchanged).
template <class T>
struct VirtualAnyLabelSampler {
  VirtualSampler<T, std::uint8_t> v;
  VoxelType label_type = VoxelType::U8;

  SL_HOST_DEVICE float sample(const vec3& p, const SampleContext& c) const { return v.sample(p, c); }
  SL_HOST_DEVICE vec3 gradient(const vec3& p, const vec3& spacing, const SampleContext& c) const {
    return v.gradient(p, spacing, c);
  }
  // VirtualSampler::label_at with the label type chosen at run time: the brick serving p comes from
  // the same cursor as the intensity (locate), its label slot is read as u8, u16 or u32.
  SL_HOST_DEVICE std::uint32_t label_at(const vec3& p, const SampleContext& c) const {
    if (!v.has_labels) return 0u;
    const auto& k = v.locate(p, c);
    if (!k.entry.is_resident()) return 0u;
    return dispatch_label(
        label_type, [&](auto tag) { return labels<decltype(tag)>(k.entry.slot(), k.id).label_at(p); },
        [&] { return labels<std::uint8_t>(k.entry.slot(), k.id).label_at(p); });
  }
  template <class L>
  SL_HOST_DEVICE SlotSampler<L> labels(std::uint32_t slot, BrickId id) const {
    return v.cache.template label_sampler<L>(slot, *v.layout, id);
  }
};

// Out of core, hardware trilinear: the resident brick is read from a 3D texture atlas of slots.
// The page-table walk, fallback to coarser levels, miss, usage and shortfall reporting are
// VirtualSampler::serve.
// The texture unit interpolates with 8-bit fixed-point weights, so images are close to, not
// bit-identical with, the CPU's (the software sampler above is the default for that reason).
template <class T>
struct TextureVirtualSampler {
  VirtualAnyLabelSampler<T> base;
  cudaTextureObject_t atlas = 0;
  ivec3 cells{1};     // slots per atlas axis
  float scale = 1.0f; // normalized-float reads back to raw values (255, 65535; 1 for f32)

  SL_HOST_DEVICE float sample(const vec3& p, const SampleContext& c) const {
    const auto& k = base.v.serve(p, c);  // the wanted brick or its finest resident ancestor, counted
    const PageEntry e = k.entry;
    if (e.is_resident()) {
#if defined(__CUDA_ARCH__)
      const BrickLayout& L = *base.v.layout;
      const BrickId id = k.id;
      const int level = id.level();
      vec3 u = p * L.level_inv_spacing(level) - 0.5f;  // voxel centres at integers, as SlotSampler
      u = glm::clamp(u, vec3(0.0f), vec3(L.dims(level) - 1));
      const std::uint32_t s = e.slot();
      const ivec3 cell(int(s % std::uint32_t(cells.x)), int((s / std::uint32_t(cells.x)) % std::uint32_t(cells.y)),
                       int(s / std::uint32_t(cells.x * cells.y)));
      // Stored voxel k of the slot sits at texel cell * S + k, whose centre is at + 0.5.
      const vec3 t = vec3(cell * L.stored_size()) + (u - vec3(L.brick_origin(id) - kBrickApron)) + 0.5f;
      return tex3D<float>(atlas, t.x, t.y, t.z) * scale;
#else
      return 0.0f;  // host code never samples the atlas
#endif
    }
    if (e.state() == PageEntry::State::Constant) return e.constant_value(base.v.cache.voxel_type);
    return 0.0f;
  }
  SL_HOST_DEVICE std::uint32_t label_at(const vec3& p, const SampleContext& c) const { return base.label_at(p, c); }
  // Central differences one level voxel apart, as VirtualSampler::gradient, through the atlas.
  SL_HOST_DEVICE vec3 gradient(const vec3& p, const vec3& spacing, const SampleContext& c) const {
    return central_difference_gradient(p, spacing * float(1 << c.level), [&](const vec3& q) { return sample(q, c); });
  }
};

}  // namespace sl::cuda
