#include "cache/out_of_core/cast_device.h"

#include <algorithm>

#include "cache/virtual_sampler.h"
#include "core/frame/cast_tiles.h"

namespace sl {

void split_page_table_update(const PageTableUpdate& u, const std::vector<bool>& in_flight, PageTableUpdate& now,
                             PageTableUpdate& later) {
  // Directory words carry no data dependency: a newly allocated page reads Unmapped until its words
  // arrive.
  now.dir_index.insert(now.dir_index.end(), u.dir_index.begin(), u.dir_index.end());
  now.dir_value.insert(now.dir_value.end(), u.dir_value.begin(), u.dir_value.end());
  for (std::size_t k = 0; k < u.pool_index.size(); ++k) {
    const PageEntry e{u.pool_value[k]};
    const bool wait = e.is_resident() && e.slot() < in_flight.size() && in_flight[e.slot()];
    PageTableUpdate& dst = wait ? later : now;
    dst.pool_index.push_back(u.pool_index[k]);
    dst.pool_value.push_back(u.pool_value[k]);
  }
}

namespace {

template <class T, class L>
void cast_typed(const CastParams& p, const RayGenerator& gen, const Box3& vbox, const SkipInputs& skip,
                std::uint32_t frame_number, const VirtualMemoryView& vm, Frame& frame) {
  VirtualSampler<T, L> sampler;
  sampler.layout = vm.layout;
  sampler.page_table = vm.page_table;
  sampler.cache = vm.cache;
  sampler.misses = vm.misses;
  sampler.frame = frame_number;
  sampler.has_labels = vm.has_labels;
  sampler.shortfall = vm.shortfall;
  const RayCaster<VirtualSampler<T, L>> caster{p, sampler};
  cast_frame(caster, gen, vbox, skip, frame);
}

template <class T>
void cast_labels_typed(const CastParams& p, const RayGenerator& gen, const Box3& vbox, const SkipInputs& skip,
                       std::uint32_t n, const VirtualMemoryView& vm, Frame& f) {
  // The cache holds integer labels only (a float label volume is refused when it is opened).
  dispatch_label(
      vm.has_labels ? vm.cache.label_type : VoxelType::U8,
      [&](auto tag) { cast_typed<T, decltype(tag)>(p, gen, vbox, skip, n, vm, f); },
      [&] { cast_typed<T, std::uint32_t>(p, gen, vbox, skip, n, vm, f); });
}

}  // namespace

void add_shortfall(const SampleShortfall& host, std::span<const std::uint64_t> device) {
  if (!host.counters) return;
  SL_CHECK(device.size() == SampleShortfall::kWords);
  for (std::uint32_t w = 0; w < SampleShortfall::kWords; ++w) host.counters[w] += device[w];
}

void cast_virtual_frame(const CastParams& p, const RayGenerator& gen, const Box3& vbox, const SkipInputs& skip,
                        std::uint32_t n, const VirtualMemoryView& vm, Frame& f) {
  dispatch_voxel(vm.cache.voxel_type,
                 [&](auto tag) { cast_labels_typed<decltype(tag)>(p, gen, vbox, skip, n, vm, f); });
}

}  // namespace sl
