#include "core/frame/stats.h"

#include <cstdio>
#include <nlohmann/json.hpp>

namespace sl {

void record_cast_counters(const CastCounters& c, bool skipping, Stats& st) {
  st.samples = c.samples;
  st.useful_samples = c.useful;
  st.rays = c.rays;
  st.occupancy_misses = c.misses;
  if (skipping && st.rays > 0) {
    st.depth_complexity_avg = double(c.dc_sum) / double(st.rays);
    st.depth_complexity_max = c.dc_max;
    st.depth_complexity_min = c.dc_min == 0xFFFFFFFFu ? 0u : c.dc_min;
  }
}

std::string stats_to_json(const Stats& s) {
  nlohmann::json j;
  j["width"] = s.width;
  j["height"] = s.height;
  j["backend"] = s.backend;
  j["method"] = s.method;
  j["mode"] = s.mode;
  j["time_ms"] = {{"total", s.time_ms.total},       {"metadata", s.time_ms.metadata},
                  {"tree", s.time_ms.tree},         {"geometry", s.time_ms.geometry},
                  {"order", s.time_ms.order},       {"lists", s.time_ms.lists},
                  {"raycast", s.time_ms.raycast}};
  j["samples"] = s.samples;
  j["useful_samples"] = s.useful_samples;
  j["rays"] = s.rays;
  j["boxes"] = s.boxes;
  j["events"] = s.events;
  j["occupancy_misses"] = s.occupancy_misses;
  j["list_overflows"] = s.list_overflows;
  j["list_bytes"] = s.list_bytes;
  j["list_tile_entries"] = s.list_tile_entries;
  j["list_slab_tests"] = s.list_slab_tests;
  j["metadata_blocks"] = s.metadata_blocks;
  j["metadata_computed"] = s.metadata_computed;
  if (s.cache.present) j["metadata_bytes"] = s.metadata_bytes;
  j["tree"] = {{"nodes", s.tree_nodes}};
  j["tree_bytes"] = s.tree_bytes;
  j["depth_complexity"] = {{"avg", s.depth_complexity_avg}, {"max", s.depth_complexity_max}, {"min", s.depth_complexity_min}};
  if (s.cache.present) {
    j["frame"] = s.cache.frame;
    j["cache"] = {{"resident_mb", s.cache.resident_mb}, {"hits", s.cache.hits},       {"misses", s.cache.misses},
                  {"loads", s.cache.loads},             {"evictions", s.cache.evictions}, {"pending", s.cache.pending},
                  {"failed", s.cache.failed},           {"bricks_missing", s.cache.bricks_missing},
                  {"bricks_retried", s.cache.bricks_retried}, {"retries", s.cache.retries},
                  {"recovered", s.cache.recovered},   {"prefetched", s.cache.prefetched},
                  {"prefetch_hits", s.cache.prefetch_hits}, {"prefetch_pending", s.cache.prefetch_pending},
                  {"stall", s.cache.stall}, {"slots", s.cache.slots}, {"slot_bytes", s.cache.slot_bytes},
                  {"depth_passes", s.cache.depth_passes}, {"depth_pass", s.cache.depth_pass},
                  {"depth_pass_bytes", s.cache.depth_pass_bytes}};
    j["completeness"] = s.cache.completeness;
    j["lod_coarsened"] = s.cache.lod_coarsened;
    j["page_table_bytes"] = s.cache.page_table_bytes;
    j["converged_at_frame"] = s.cache.converged_at_frame;
  }
  return j.dump(2);
}

std::string stats_summary(const Stats& s) {
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "%dx%d %s %s %s: %.1f ms (raycast %.1f ms), %llu samples (%.1f%% useful)",
                s.width, s.height, s.backend.c_str(), s.method.c_str(), s.mode.c_str(),
                s.time_ms.total, s.time_ms.raycast, (unsigned long long)s.samples,
                s.samples ? 100.0 * double(s.useful_samples) / double(s.samples) : 0.0);
  std::string line = buf;
  if (s.depth_complexity_max > 0) {
    std::snprintf(buf, sizeof buf, ", depth complexity avg %.2f max %u", s.depth_complexity_avg,
                  s.depth_complexity_max);
    line += buf;
  }
  if (s.cache.present) {
    std::snprintf(buf, sizeof buf, "; frame %u: %.0f MB resident, %llu loads, %llu misses, %llu pending%s",
                  s.cache.frame, s.cache.resident_mb, (unsigned long long)s.cache.loads,
                  (unsigned long long)s.cache.misses, (unsigned long long)s.cache.pending,
                  s.cache.converged_at_frame >= 0
                      ? (", converged at frame " + std::to_string(s.cache.converged_at_frame)).c_str()
                      : ", not converged");
    line += buf;
    std::snprintf(buf, sizeof buf, ", completeness %.3f, %.1f%% coarsened, %llu bricks missing",
                  s.cache.completeness, 100.0 * s.cache.lod_coarsened, (unsigned long long)s.cache.bricks_missing);
    line += buf;
    if (s.cache.failed > 0 || s.cache.bricks_retried > 0) {
      std::snprintf(buf, sizeof buf, "; %llu bricks failed, %llu retried (%llu retries, %llu recovered)",
                    (unsigned long long)s.cache.failed, (unsigned long long)s.cache.bricks_retried,
                    (unsigned long long)s.cache.retries, (unsigned long long)s.cache.recovered);
      line += buf;
    }
  }
  return line;
}

}  // namespace sl
