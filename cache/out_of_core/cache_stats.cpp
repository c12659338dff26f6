// The out-of-core renderer's cache statistics of a frame (core/frame/stats.h, CacheStats).
#include <algorithm>

#include "cache/out_of_core/renderer.h"

namespace sl {

void OutOfCoreRenderer::fill_cache_stats(const FrameStart& start, const FrameLod& lod, Stats& st) {
  const BrickCache& cache = residency_.cache();
  CacheStats& c = st.cache;
  c.present = true;
  c.frame = frame_;
  c.resident_mb = cache.resident_mb();
  count_used_slots(c);
  c.loads = residency_.loads_this_frame();
  c.stall = start.waiting && c.loads == 0;
  c.prefetched = prefetch_.resident_this_frame();
  c.evictions = cache.evictions() - start.evictions;
  count_loader(c);
  c.page_table_bytes = residency_.page_table().memory_bytes();
  count_completeness(st);
  count_misses(c);
  const double slot_mb = double(cache.slot_bytes()) / double(1 << 20);
  c.cache_mb = double(cache.slot_count()) * slot_mb;
  c.slots = cache.slot_count();
  c.slot_bytes = cache.slot_bytes();
  if (pressure_.unfit_working_set() > cache.slot_count()) {
    c.working_set_mb = double(pressure_.unfit_working_set()) * slot_mb;
    c.working_set_level = pressure_.working_set_level(lod);
  }
  residency_.set_slots_used_last(c.hits);
}

void OutOfCoreRenderer::count_used_slots(CacheStats& c) {
  const BrickCache& cache = residency_.cache();
  for (std::uint32_t sl = 0; sl < cache.slot_count(); ++sl) {
    if (cache.last_used(sl) != frame_) continue;
    ++c.hits;
    if (prefetch_.sampled(cache.brick_in(sl))) ++c.prefetch_hits;
  }
}

void OutOfCoreRenderer::count_loader(CacheStats& c) const {
  // The frame's own loads in flight; prefetches are not what the view waits for.
  const std::size_t in_flight = residency_.loader().pending();
  const std::size_t prefetches = prefetch_.in_flight();
  c.pending = in_flight > prefetches ? in_flight - prefetches : 0;
  c.prefetch_pending = in_flight - c.pending;
  const LoaderCounts lc = residency_.loader().counts();
  c.failed = lc.failed;
  c.bricks_retried = lc.bricks_retried;
  c.retries = lc.retries;
  c.recovered = lc.recovered;
}

// Shares of the samples not served at their desired level, and coarsened by pressure.
void OutOfCoreRenderer::count_completeness(Stats& st) const {
  std::uint64_t incomplete = 0, coarsened = 0, left_out = 0;
  for (std::uint32_t k = 0; k < SampleShortfall::kStripes; ++k) {
    incomplete += shortfall_[k * SampleShortfall::kStride];
    coarsened += shortfall_[k * SampleShortfall::kStride + 1];
    left_out += shortfall_[k * SampleShortfall::kStride + 2];
  }
  st.cache.samples_left_out = left_out;
  // Shares of every sample of the frame, taken or left out.
  const double samples = double(std::max<std::uint64_t>(st.samples + left_out, 1));
  st.cache.completeness = 1.0 - std::min(1.0, double(incomplete) / samples);
  st.cache.lod_coarsened = std::min(1.0, double(coarsened) / samples);
}

// Failed bricks are missed every frame, but nothing will load them: not counted as misses.
void OutOfCoreRenderer::count_misses(CacheStats& c) const {
  for (const BrickId id : residency_.misses().drain()) {
    if (residency_.loader().failed(id)) continue;
    ++c.misses;
    if (!residency_.page_table().get(id).is_resident()) ++c.bricks_missing;
  }
}

}  // namespace sl
