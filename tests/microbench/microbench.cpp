// sl_microbench: Google Benchmark micro-benchmarks of the hot loops. Every input is made by
// the real pipeline from one synthetic data set, generate_volume("neurites", 256³) with its labels, seen
// by default_camera() at 512×512 with default_transfer_function(0, 255) and ~10 % of the labels enabled
// ("fraction:0.1:1") — the sparse setting of the paper's Table 1. Inputs are built once, outside the
// timed loops; TBB code in a timed loop runs on one thread (numbers are per core) unless
// --sl_threads=N is given. Numbers are for people, never asserted (STYLE.md #11).
//
//  BM_SegmentListBuild/<block>   build_segment_lists (the CPU tile builder, paper §7.3, Alg. 4-5) for
//      the whole view, from the geometry (Alg. 2) and visibility order (Alg. 3) of the occupancy tree
//      over culling blocks of <block>³, into one buffer reused across iterations (as a renderer does).
//      items = pixels. Counters: entries (visibility entries rasterized), events (in all lists),
//      segments/pixel (depth complexity, paper Fig. 7), tests/pixel (slab tests run per pixel, FRONT
//      entries only: BACK entries reuse them), list_MB (the compact lists' storage).
//  BM_MergeRules/add_box_event   the per-pixel list insertion, one slab test per entry: for 384
//      pixels of the real view (block 16), the recorded sequence of (box, front/back, class, parent
//      class) of the entries whose rectangles cover the pixel, replayed per pixel into add_box_event
//      (slab test + Alg. 5 merge rules) and an empty list of kMaxEvents capacity. items = box events
//      fed (hits and misses).
//  BM_MergeRules/add_event       the same pixels, only the events that hit (t, ENTRY/EXIT, class)
//      replayed into add_event: the merge rules alone. items = events inserted.
//  BM_SampleClassifyComposite/<type>  RayCaster<Sampler>::march over every sample of the rays of the
//      512² view (no skipping, as method `none`): trilinear sample + TF classify + front-to-back
//      composite, DVR. u8/u16 intensity (u16: the u8 data × 257, TF over 0..65535); _mask: label mask
//      on (label fetch for samples with opacity > 0); _simd: CastParams::simd on, eight samples at a
//      time (core/cast/sample_batch.h; where the CPU has AVX2) from the volume's bricks
//      (core/cast/bricked_volume.h) with the frame's plans (the opacity-only table), as the renderer runs
//      it; without it the scalar caster; virtual_u8:
//      the out-of-core VirtualSampler (page table + brick cache, 32³ bricks, every brick of every
//      level resident). Rays are walked
//      tile by tile (16×16, as the renderer; tiles in a scattered order so that a short run still
//      covers the whole view), 1024 rays per iteration, resuming where the last iteration stopped.
//      items = samples taken (RayAccum::samples): the "samples/s per core".
//  BM_KdRestartStep/<block>      SkipOctreeView::step (kd-restart, DESIGN.md "Ray casting") along the same rays
//      from volume entry to exit over the min/max octree of <block>³ culling blocks (same classes as
//      the segment lists). items = steps; counter nodes/step (nodes visited per descent).
//
// Run:  build-mb/tests/microbench/sl_microbench [--benchmark_filter=REGEX] [--benchmark_min_time=SEC]
#include <benchmark/benchmark.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <type_traits>
#include <vector>

#include "cache/brick_cache.h"
#include "core/scene/generate.h"
#include "cache/miss_buffer.h"
#include "cache/page_table.h"
#include "cache/virtual_sampler.h"
#include "cache/volume_source.h"
#include "core/occupancy/block_metadata.h"
#include "core/cast/bricked_volume.h"
#include "core/scene/camera.h"
#include "core/cast/cast_pixel.h"
#include "core/frame/in_core_renderer.h"
#include "core/occupancy/culling.h"
#include "core/scene/labels.h"
#include "core/occupancy/occupancy_geometry.h"
#include "core/occupancy/occupancy_tree.h"
#include "core/occupancy/octree_skip.h"
#include "core/util/parallel.h"
#include "core/cast/raycast.h"
#include "core/lists/segment_list.h"
#include "core/lists/segment_list_builder.h"
#include "core/scene/transfer_function.h"
#include "core/lists/visibility_order.h"

namespace sl {
namespace {

constexpr int kVolumeEdge = 256;
constexpr int kView = 512;
constexpr float kStep = 0.5f;           // sample distance in voxels (RenderSettings default)
constexpr int kRaysPerIteration = 1024;
constexpr int kMergePixels = 384;
int g_threads = 1;  // TBB threads inside timed loops (--sl_threads=N)

// Caps TBB inside a timed loop; built after the (parallel) setup.
struct TimedThreads {
  tbb::global_control gc{tbb::global_control::max_allowed_parallelism, std::size_t(g_threads)};
};

// The data set, the view and the transfer function every benchmark shares.
struct BenchScene {
  GeneratedVolume gv;
  std::shared_ptr<Volume> intensity, labels;  // u8, u16 (shared with the out-of-core source)
  Volume intensity_u16;                       // intensity * 257
  TransferFunction tf = default_transfer_function(0.0f, 255.0f);
  TransferFunction tf_u16 = default_transfer_function(0.0f, 65535.0f);
  LabelSet enabled;
  RayGenerator gen;
  Box3 vbox;
  // Every ray of the view that meets the volume, tile by tile (16×16 screen tiles, scattered order).
  struct RaySpan {
    Ray ray;
    float t_entry, t_exit;
    int k_end;
    int x, y;  // pixel
  };
  std::vector<RaySpan> rays;
};

const BenchScene& scene() {
  static const std::unique_ptr<BenchScene> s = [] {
    auto s = std::make_unique<BenchScene>();
    s->gv = generate_volume("neurites", ivec3(kVolumeEdge), 1);
    s->intensity = std::make_shared<Volume>(std::move(s->gv.intensity));
    s->labels = std::make_shared<Volume>(std::move(s->gv.labels));
    // The samplers below are instantiated for these types (generate.h: u8 intensity, u16 labels).
    SL_CHECK(s->intensity->type() == VoxelType::U8 && s->labels->type() == VoxelType::U16);
    VolumeDesc d16 = s->intensity->desc();
    d16.type = VoxelType::U16;
    s->intensity_u16 = Volume(d16);
    const std::uint8_t* src = s->intensity->as<std::uint8_t>();
    std::uint16_t* dst = s->intensity_u16.as<std::uint16_t>();
    const std::size_t n = std::size_t(kVolumeEdge) * kVolumeEdge * kVolumeEdge;
    for (std::size_t i = 0; i < n; ++i) dst[i] = std::uint16_t(src[i] * 257u);
    s->enabled = parse_enable_spec("fraction:0.1:1", s->gv.label_count);
    const vec3 extent = s->intensity->desc().extent();
    s->gen = make_ray_generator(default_camera(extent), kView, kView);
    s->vbox = Box3{vec3(0.0f), extent};
    const float inv_dt = 1.0f / (kStep * s->intensity->desc().min_spacing());
    // Tiles in a scattered order (tile i -> i * 617 mod 1024; 617 is odd, so it is a permutation):
    // rays within a tile stay coherent, as the renderer casts them, while any batch of a few tiles
    // samples the whole view (a short run does not measure only the top rows).
    constexpr int T = kTileSize, kTilesX = kView / T, kTiles = kTilesX * kTilesX;
    static_assert(kView % T == 0 && kTiles == 1024);
    for (int i = 0; i < kTiles; ++i) {
      const int tile = int((std::int64_t(i) * 617) % kTiles);
      const int tx = (tile % kTilesX) * T, ty = (tile / kTilesX) * T;
      for (int y = ty; y < ty + T; ++y)
        for (int x = tx; x < tx + T; ++x) {
          BenchScene::RaySpan r;
          if (!pixel_span(s->gen, s->vbox, x, y, r.ray, r.t_entry, r.t_exit)) continue;
          r.k_end = sample_index(r.t_exit, r.t_entry, inv_dt);
          r.x = x;
          r.y = y;
          s->rays.push_back(r);
        }
    }
    return s;
  }();
  return *s;
}

// metadata → block classes → occupancy tree → geometry → visibility order (InCoreRenderer::
// prepare_skipping, DVR with the label mask), plus the octree baseline's tree, for one block size.
struct Skipping {
  std::optional<BlockMetadataTable> metadata;
  std::vector<OccupancyClass> classes;
  std::optional<OccupancyTree> tree;
  OccupancyGeometry geometry;
  std::vector<VisibilityEntry> order;
  std::optional<SkipOctree> octree;
};

const Skipping& skipping(int block) {
  static std::mutex m;
  static std::map<int, std::unique_ptr<Skipping>> cache;
  const std::lock_guard lock(m);
  auto& k = cache[block];
  if (!k) {
    const BenchScene& s = scene();
    k = std::make_unique<Skipping>();
    const BlockGrid grid = make_block_grid(s.intensity->dims(), s.intensity->desc().spacing, block);
    const VolumeView lv = s.labels->view();
    k->metadata = compute_all_block_metadata(grid, s.intensity->view(), &lv);
    CullParams cull;
    cull.mode = RenderMode::Dvr;
    cull.tf = &s.tf;
    cull.enabled = &s.enabled;
    k->classes = classify_blocks(*k->metadata, cull);
    k->tree = OccupancyTree::from_block_classes(grid, k->classes);
    k->geometry = build_occupancy_geometry(*k->tree);
    k->order = build_visibility_order(*k->tree, k->geometry, view_point(s.gen));
    k->octree.emplace(grid, k->classes);
  }
  return *k;
}

// ---------------------------------------------------------------------------------------------------
void BM_SegmentListBuild(benchmark::State& state) {
  const BenchScene& s = scene();
  const Skipping& k = skipping(int(state.range(0)));
  SegmentListBuffer lists;
  const TimedThreads threads;
  SegmentListStats st;
  for (auto _ : state) {
    st = build_segment_lists(k.geometry, k.order, s.gen, lists, 0.0f);
    benchmark::DoNotOptimize(st);
    benchmark::DoNotOptimize(lists.counts.data());
    benchmark::ClobberMemory();
  }
  const double pixels = double(kView) * kView;
  state.SetItemsProcessed(state.iterations() * std::int64_t(pixels));
  state.counters["entries"] = benchmark::Counter(double(k.order.size()));
  state.counters["events"] = benchmark::Counter(double(st.events));
  state.counters["segments/pixel"] = benchmark::Counter(double(st.segments) / pixels);
  state.counters["tests/pixel"] = benchmark::Counter(double(st.slab_tests) / pixels);
  state.counters["list_MB"] = benchmark::Counter(double(lists.storage_bytes()) / double(1 << 20));
  state.counters["overflows"] = benchmark::Counter(double(st.overflows));
}
// Process CPU time: with --sl_threads=N > 1 the TBB workers' time counts too (items/s stays per core).
BENCHMARK(BM_SegmentListBuild)
    ->ArgName("block")
    ->Arg(8)
    ->Arg(16)
    ->Arg(32)
    ->MeasureProcessCPUTime()
    ->Unit(benchmark::kMillisecond);

// ---------------------------------------------------------------------------------------------------
// What the tile builder feeds one pixel's list, in order: every visibility entry whose conservative
// screen rectangle covers the pixel (segment_list_builder.cpp), and the events that hit.
struct BoxEvent {
  Box3 box;
  bool front;
  OccupancyClass cls, parent_cls;
};
struct HitEvent {
  float t;
  EventType type;
  OccupancyClass cls;
};
struct MergeTrace {
  std::vector<Ray> rays;                                 // per pixel
  std::vector<std::size_t> box_begin, hit_begin;         // per pixel + 1 (offsets)
  std::vector<BoxEvent> boxes;
  std::vector<HitEvent> hits;
};

const MergeTrace& merge_trace() {
  static const std::unique_ptr<MergeTrace> tr = [] {
    const BenchScene& s = scene();
    const Skipping& k = skipping(16);
    std::vector<ScreenRect> rects(k.geometry.boxes.size());
    for (std::size_t i = 0; i < rects.size(); ++i) rects[i] = conservative_screen_rect(k.geometry.boxes[i].box, s.gen);
    auto t = std::make_unique<MergeTrace>();
    t->box_begin.push_back(0);
    t->hit_begin.push_back(0);
    // Evenly spaced over the pixels whose ray meets the volume (those with any work).
    const std::size_t stride = s.rays.size() / kMergePixels;
    for (int p = 0; p < kMergePixels; ++p) {
      const BenchScene::RaySpan& px = s.rays[std::size_t(p) * stride];
      const Ray ray = px.ray;
      t->rays.push_back(ray);
      for (const VisibilityEntry& v : k.order) {
        const ScreenRect& r = rects[v.box];
        if (r.empty() || px.x < r.x0 || px.x > r.x1 || px.y < r.y0 || px.y > r.y1) continue;
        const OccupancyBox& b = k.geometry.boxes[v.box];
        const bool front = v.face == Face::Front;
        t->boxes.push_back({b.box, front, b.cls, b.parent_cls});
        // add_box_event's hit test and arguments to add_event, verbatim.
        const Interval iv = intersect(ray, b.box);
        if (iv.empty() || !(iv.t1 > 0.0f)) continue;
        if (front) {
          t->hits.push_back({iv.t0 > 0.0f ? iv.t0 : 0.0f, EventType::Entry, b.cls});
        } else {
          t->hits.push_back({iv.t1, EventType::Exit, b.parent_cls});
        }
      }
      t->box_begin.push_back(t->boxes.size());
      t->hit_begin.push_back(t->hits.size());
    }
    // The trace is what the builder feeds: replayed, it gives the builder's lists event for event.
    SegmentListBuffer built;
    build_segment_lists(k.geometry, k.order, s.gen, built, 0.0f);
    for (std::size_t p = 0; p + 1 < t->box_begin.size(); ++p) {
      const BenchScene::RaySpan& px = s.rays[p * stride];
      RayEvent ev[kMaxEvents];
      std::uint32_t count = 0;
      float t_seen = kNoEventYet;
      for (std::size_t i = t->box_begin[p]; i < t->box_begin[p + 1]; ++i) {
        const BoxEvent& b = t->boxes[i];
        add_box_event(ev, count, t_seen, kMaxEvents, px.ray, b.box, b.front, b.cls, b.parent_cls, 0.0f);
      }
      const std::size_t q = built.pixel(px.x, px.y);
      SL_CHECK(count == built.counts[q]);
      SL_CHECK(std::memcmp(ev, built.list(q), sizeof(RayEvent) * (count & kListCountMask)) == 0);
    }
    return t;
  }();
  return *tr;
}

void BM_MergeRules_AddBoxEvent(benchmark::State& state) {
  const MergeTrace& t = merge_trace();
  constexpr std::uint32_t cap = kMaxEvents;
  RayEvent ev[kMaxEvents];
  void* escaped = ev;  // the list's stores stay observable (ClobberMemory per pixel)
  benchmark::DoNotOptimize(escaped);
  std::uint64_t events = 0;
  for (auto _ : state) {
    for (std::size_t p = 0; p + 1 < t.box_begin.size(); ++p) {
      std::uint32_t count = 0;
      float t_seen = kNoEventYet;
      const Ray ray = t.rays[p];
      for (std::size_t i = t.box_begin[p]; i < t.box_begin[p + 1]; ++i) {
        const BoxEvent& b = t.boxes[i];
        add_box_event(ev, count, t_seen, cap, ray, b.box, b.front, b.cls, b.parent_cls, 0.0f);
      }
      events += count & kListCountMask;
      benchmark::DoNotOptimize(count);
      benchmark::ClobberMemory();
    }
  }
  state.SetItemsProcessed(state.iterations() * std::int64_t(t.boxes.size()));
  state.counters["pixels"] = benchmark::Counter(double(t.rays.size()));
  state.counters["fed/pixel"] = benchmark::Counter(double(t.boxes.size()) / double(t.rays.size()));
  state.counters["hits/pixel"] = benchmark::Counter(double(t.hits.size()) / double(t.rays.size()));
  state.counters["kept/pixel"] =
      benchmark::Counter(double(events) / double(state.iterations()) / double(t.rays.size()));
}
BENCHMARK(BM_MergeRules_AddBoxEvent)->Name("BM_MergeRules/add_box_event");

void BM_MergeRules_AddEvent(benchmark::State& state) {
  const MergeTrace& t = merge_trace();
  constexpr std::uint32_t cap = kMaxEvents;
  RayEvent ev[kMaxEvents];
  void* escaped = ev;
  benchmark::DoNotOptimize(escaped);
  for (auto _ : state) {
    for (std::size_t p = 0; p + 1 < t.hit_begin.size(); ++p) {
      std::uint32_t count = 0;
      float t_seen = kNoEventYet;
      for (std::size_t i = t.hit_begin[p]; i < t.hit_begin[p + 1]; ++i) {
        const HitEvent& h = t.hits[i];
        add_event(ev, count, t_seen, cap, h.t, h.type, h.cls, 0.0f);
      }
      benchmark::DoNotOptimize(count);
      benchmark::ClobberMemory();
    }
  }
  state.SetItemsProcessed(state.iterations() * std::int64_t(t.hits.size()));
  state.counters["pixels"] = benchmark::Counter(double(t.rays.size()));
  state.counters["events/pixel"] = benchmark::Counter(double(t.hits.size()) / double(t.rays.size()));
}
BENCHMARK(BM_MergeRules_AddEvent)->Name("BM_MergeRules/add_event");

// ---------------------------------------------------------------------------------------------------
CastParams dvr_params(const TransferFunction& tf, bool mask, bool simd = false) {
  const BenchScene& s = scene();
  CastParams p;
  p.mode = RenderMode::Dvr;
  p.dt = kStep * s.intensity->desc().min_spacing();
  p.inv_dt = 1.0f / p.dt;
  p.spacing = s.intensity->desc().spacing;
  p.tf = tf.view(kStep);
  p.label_mask = mask;
  if (mask) p.labels = s.enabled.view();
  p.simd = simd;
  return p;
}

template <class T>
DenseGrid<T> grid_of(const Volume& v) {
  DenseGrid<T> g;
  g.data = v.as<T>();
  g.dims = v.dims();
  g.inv_spacing = 1.0f / v.desc().spacing;
  return g;
}

// Marches kRaysPerIteration whole rays per iteration, resuming at the next ray of the view.
template <class Sampler>
void march_rays(benchmark::State& state, const RayCaster<Sampler>& caster) {
  const BenchScene& s = scene();
  // The batch's per-frame plans, as the renderer's tile loop makes them (core/frame/cast_tiles.h): its
  // inputs and the opacity-only table its gathers read.
  const BatchPlans<Sampler> plans(caster, nullptr);
  std::size_t next = 0;
  std::uint64_t samples = 0, useful = 0;
  for (auto _ : state) {
    for (int i = 0; i < kRaysPerIteration; ++i) {
      const BenchScene::RaySpan& r = s.rays[next];
      next = next + 1 == s.rays.size() ? 0 : next + 1;
      RayAccum acc;
      caster.march(r.ray, r.t_entry, 0, r.k_end, acc, false, nullptr, &plans);
      benchmark::DoNotOptimize(acc);
      samples += acc.samples;
      useful += acc.useful_samples;
    }
  }
  state.SetItemsProcessed(std::int64_t(samples));
  state.counters["samples/ray"] = benchmark::Counter(double(samples) / double(state.iterations() * kRaysPerIteration));
  state.counters["useful"] = benchmark::Counter(samples ? double(useful) / double(samples) : 0.0);
}

template <class T, bool mask, bool simd>
void BM_SampleDense(benchmark::State& state) {
  const BenchScene& s = scene();
  const Volume& vol = std::is_same_v<T, std::uint8_t> ? *s.intensity : s.intensity_u16;
  const TransferFunction& tf = std::is_same_v<T, std::uint8_t> ? s.tf : s.tf_u16;
  // With simd the batch reads the volume's bricks, as the in-core renderer gives it (bricked_volume()).
  std::optional<BrickedVolume> bricks;
  if (simd) bricks.emplace(vol.data(), vol.dims(), int(sizeof(T)));
  const RayCaster<DenseSampler<T, std::uint16_t>> caster{
      dvr_params(tf, mask, simd),
      {grid_of<T>(vol), grid_of<std::uint16_t>(*s.labels), bricks ? &*bricks : nullptr}};
  march_rays(state, caster);
}
BENCHMARK_TEMPLATE(BM_SampleDense, std::uint8_t, false, false)->Name("BM_SampleClassifyComposite/u8_dvr");
BENCHMARK_TEMPLATE(BM_SampleDense, std::uint8_t, false, true)->Name("BM_SampleClassifyComposite/u8_dvr_simd");
BENCHMARK_TEMPLATE(BM_SampleDense, std::uint8_t, true, false)->Name("BM_SampleClassifyComposite/u8_dvr_mask");
BENCHMARK_TEMPLATE(BM_SampleDense, std::uint8_t, true, true)->Name("BM_SampleClassifyComposite/u8_dvr_mask_simd");
BENCHMARK_TEMPLATE(BM_SampleDense, std::uint16_t, false, false)->Name("BM_SampleClassifyComposite/u16_dvr");
BENCHMARK_TEMPLATE(BM_SampleDense, std::uint16_t, false, true)->Name("BM_SampleClassifyComposite/u16_dvr_simd");
BENCHMARK_TEMPLATE(BM_SampleDense, std::uint16_t, true, false)->Name("BM_SampleClassifyComposite/u16_dvr_mask");
BENCHMARK_TEMPLATE(BM_SampleDense, std::uint16_t, true, true)->Name("BM_SampleClassifyComposite/u16_dvr_mask_simd");

// The out-of-core path with every brick of every level resident: what page-table translation and
// brick-slot sampling cost on top of the dense sampler (no misses, no loads).
struct VirtualData {
  std::unique_ptr<MemoryVolumeSource> source;
  BrickLayout layout;
  std::unique_ptr<PageTable> page_table;
  std::unique_ptr<BrickCache> cache;
  std::unique_ptr<MissBuffer> misses;
};

VirtualData& virtual_data() {
  static const std::unique_ptr<VirtualData> v = [] {
    const BenchScene& s = scene();
    auto v = std::make_unique<VirtualData>();
    v->source = std::make_unique<MemoryVolumeSource>(s.intensity, s.labels, "neurites");
    v->layout = BrickLayout::make(v->source->desc(), 32);
    std::uint64_t bricks = 0;
    for (int l = 0; l < v->layout.levels; ++l) bricks += v->layout.brick_count(l);
    // u8 voxels, u16 labels and the voxel mask (a bit per voxel), each padded to 64 bytes.
    const std::size_t slot_bytes = std::size_t(v->layout.stored_voxels()) * (1 + 2) + v->layout.stored_voxels() / 8 + 192;
    const std::size_t mb = std::size_t(bricks) * slot_bytes / (1u << 20) + 2;
    v->page_table = std::make_unique<PageTable>(v->layout);
    v->cache = std::make_unique<BrickCache>(v->layout, VoxelType::U8, VoxelType::U16, mb);
    v->misses = std::make_unique<MissBuffer>();
    for (int l = 0; l < v->layout.levels; ++l) {
      const ivec3 n = v->layout.bricks(l);
      for (int z = 0; z < n.z; ++z)
        for (int y = 0; y < n.y; ++y)
          for (int x = 0; x < n.x; ++x) {
            const BrickId id = BrickId::pack(l, {x, y, z});
            const auto a = v->cache->allocate(id, 1);
            SL_CHECK(a.has_value());
            v->source->read_brick(v->layout, id, v->cache->slot_voxels(a->slot), v->cache->slot_labels(a->slot));
            v->page_table->set(id, PageEntry::resident(a->slot));
          }
    }
    return v;
  }();
  return *v;
}

void BM_SampleVirtual(benchmark::State& state, bool mask) {
  const BenchScene& s = scene();
  VirtualData& v = virtual_data();
  // Fields by name: members added later (per-ray state) keep their defaults.
  VirtualSampler<std::uint8_t, std::uint16_t> sampler;
  sampler.layout = &v.layout;
  sampler.page_table = v.page_table->view();
  sampler.cache = v.cache->view();
  sampler.misses = v.misses->view();
  sampler.frame = 1;
  sampler.has_labels = true;
  const RayCaster<VirtualSampler<std::uint8_t, std::uint16_t>> caster{dvr_params(s.tf, mask), sampler};
  march_rays(state, caster);
  state.counters["misses"] = benchmark::Counter(double(v.misses->size()));
}
BENCHMARK_CAPTURE(BM_SampleVirtual, virtual_u8_dvr, false)->Name("BM_SampleClassifyComposite/virtual_u8_dvr");
BENCHMARK_CAPTURE(BM_SampleVirtual, virtual_u8_dvr_mask, true)
    ->Name("BM_SampleClassifyComposite/virtual_u8_dvr_mask");

// ---------------------------------------------------------------------------------------------------
void BM_KdRestartStep(benchmark::State& state) {
  const BenchScene& s = scene();
  const SkipOctreeView octree = skipping(int(state.range(0))).octree->view();
  std::size_t next = 0;
  std::uint64_t steps = 0, nodes = 0, nonempty = 0;
  for (auto _ : state) {
    for (int i = 0; i < kRaysPerIteration; ++i) {
      const BenchScene::RaySpan& r = s.rays[next];
      next = next + 1 == s.rays.size() ? 0 : next + 1;
      for (float t = r.t_entry; t < r.t_exit;) {
        const KdRestartStep st = octree.step(r.ray, t, r.t_exit);
        benchmark::DoNotOptimize(st);
        ++steps;
        nodes += st.nodes_visited;
        nonempty += st.cls != OccupancyClass::Empty ? 1u : 0u;
        t = st.t1;
      }
    }
  }
  state.SetItemsProcessed(std::int64_t(steps));
  state.counters["nodes/step"] = benchmark::Counter(steps ? double(nodes) / double(steps) : 0.0);
  state.counters["steps/ray"] = benchmark::Counter(double(steps) / double(state.iterations() * kRaysPerIteration));
  state.counters["nonempty"] = benchmark::Counter(steps ? double(nonempty) / double(steps) : 0.0);
}
BENCHMARK(BM_KdRestartStep)->ArgName("block")->Arg(8)->Arg(16)->Arg(32);

}  // namespace
}  // namespace sl

// Own main: takes --sl_threads=N (TBB threads in timed loops, default 1) before Google Benchmark's flags.
int main(int argc, char** argv) {
  int out = 1;
  for (int i = 1; i < argc; ++i) {
    if (std::strncmp(argv[i], "--sl_threads=", 13) == 0) {
      sl::g_threads = std::max(1, std::atoi(argv[i] + 13));
    } else {
      argv[out++] = argv[i];
    }
  }
  argc = out;
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::AddCustomContext("sl_threads", std::to_string(sl::g_threads));
  const sl::BenchScene& s = sl::scene();
  benchmark::AddCustomContext("sl_data", "neurites " + std::to_string(sl::kVolumeEdge) + "^3, " +
                                             std::to_string(s.gv.label_count) + " labels, " +
                                             std::to_string(s.enabled.count()) + " enabled; view " +
                                             std::to_string(sl::kView) + "^2, " + std::to_string(s.rays.size()) +
                                             " rays meet the volume");
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
