// The OpenGL builder of ray segment lists (paper §7 and §9, Alg. 4-5; DESIGN.md "Ray segment lists"): one rectangle
// per visibility-order entry, in order — the box's conservative_screen_rect, the very rectangle the CPU
// tile builder uses — whose fragment shader rebuilds the pixel's ray (RayGenerator::ray), runs the
// slab test of core/util/ray.h and turns a hit into the entry's event. Two ways to apply the events:
//  - interlock: GL_ARB_fragment_shader_interlock (pixel_interlock_ordered) or the NV variant; the
//    fragment applies add_event (a GLSL mirror of core/lists/segment_list.h) to the pixel's list in an SSBO
//    inside the ordered critical section;
//  - fallback (no interlock, e.g. Mesa llvmpipe): fragments append (entry index, t) records to
//    per-pixel linked lists in a global pool; a compute pass sorts each pixel's records by entry index
//    and applies the same add_event.
// Either way the lists equal build_segment_lists's for the same inputs. On the GPU each pixel has a
// fixed capacity (events of pixel i at [i * capacity ...), count words with the overflow flag); a
// list that needs more is made conservative (add_event's tail rule: its open last segment is sampled
// to the volume exit) and counted in SegmentListStats::overflows, so only such lists differ from the
// CPU builder's, which has no capacity. read_back compacts the lists into the CPU builder's layout
// (compact_fixed_lists), the one the casters read.
//
// Large images are built in bands of rows: a band's lists must fit one shader-storage binding
// (GL_MAX_SHADER_STORAGE_BLOCK_SIZE, 128 MiB on llvmpipe).
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "core/scene/camera.h"
#include "core/occupancy/occupancy_geometry.h"
#include "core/lists/segment_list.h"
#include "core/lists/segment_list_builder.h"
#include "core/lists/visibility_order.h"
#include "gl/gl_context.h"

namespace sl {

enum class GlListPath { Interlock, Fallback };
const char* to_string(GlListPath path);  // "interlock" / "fallback"

struct GlBuilderOptions {
  enum class Path { Auto, Interlock, Fallback };
  // Auto: interlock when the context has it, else the fallback. Interlock without the extension is a
  // GlError.
  Path path = Path::Auto;
  // Fallback: records one pixel's resolve can sort (a private array of the compute shader). A pixel
  // with more hit entries gets a conservative list and is counted in GlBuildStats::dropped_pixels.
  std::uint32_t max_records_per_pixel = 512;
  // Fallback: bytes of the record pool (12 bytes per record); also capped by the storage-block limit.
  // A band needing more is split in halves; a band of 4 rows that still does not fit keeps what fits
  // and makes the other pixels conservative (counted).
  std::size_t max_record_bytes = std::size_t(1) << 30;
  // Bytes of one band's lists (0: the storage-block limit). Tests use small bands.
  std::size_t max_band_bytes = 0;
  // Events per pixel list of build_segment_lists (2..kMaxEvents): the GPU storage is pixels x this.
  // Neurite scenes stay well below (about 30 events at most).
  std::uint32_t list_capacity = 32;
};

struct GlBuildStats {
  GlListPath path = GlListPath::Fallback;
  SegmentListStats lists;            // counted on the read-back lists (build_segment_lists only)
  int bands = 0;                     // bands drawn (after splits)
  std::uint64_t records = 0;         // fallback: hit fragments appended
  std::uint64_t redraws = 0;         // fallback: bands drawn again after the pool grew or the band split
  std::uint64_t dropped_pixels = 0;  // fallback: pixels whose records did not fit (conservative lists)
  double upload_ms = 0, raster_ms = 0, resolve_ms = 0, readback_ms = 0, total_ms = 0;
};

class GlSegmentListBuilder {
 public:
  // Compiles the programs of the chosen path. The context must be current and stay alive.
  explicit GlSegmentListBuilder(GlContext& context, GlBuilderOptions options = {});
  ~GlSegmentListBuilder();
  GlSegmentListBuilder(const GlSegmentListBuilder&) = delete;
  GlSegmentListBuilder& operator=(const GlSegmentListBuilder&) = delete;

  GlListPath path() const { return path_; }

  // Builds the lists into the GL buffers: uploads the boxes (std430, OccupancyBox as floats), the
  // order and the boxes' rectangles, draws and (fallback) resolves. capacity: events per list
  // (2..kMaxEvents); eps > 0 enables the conservative short-gap rule, as in build_segment_lists.
  GlBuildStats build(const OccupancyGeometry& geometry, std::span<const VisibilityEntry> order,
                     const RayGenerator& gen, std::uint32_t capacity = kMaxEvents, float eps = 0.0f);
  // Copies the lists of the last build into `out`, compacted (reset to the build's size).
  void read_back(SegmentListBuffer& out, GlBuildStats* stats = nullptr) const;
  // build (with options' list_capacity) + read_back, with the CPU builder's signature.
  GlBuildStats build_segment_lists(const OccupancyGeometry& geometry, std::span<const VisibilityEntry> order,
                                   const RayGenerator& gen, SegmentListBuffer& out, float eps = 0.0f);

  // Test hook (fallback only): draw the entries in this order (a permutation of 0..order.size()-1)
  // while each fragment keeps its entry's index, so records reach the resolve scrambled. Empty: draw
  // in visibility order.
  void set_draw_order_for_testing(std::vector<std::uint32_t> draw_order);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  GlListPath path_ = GlListPath::Fallback;
};

}  // namespace sl
