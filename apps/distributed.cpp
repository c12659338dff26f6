#include "apps/distributed.h"

#include <IceT.h>
#include <IceTMPI.h>
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>

#include "apps/commands.h"
#include "cache/out_of_core/work_estimate.h"
#include "core/util/error.h"
#include "core/util/process_memory.h"
#include "core/scene/render_mode.h"

namespace sl::app {

namespace {

// The error of `e` as main() prints it, and whether it is bad input (else internal).
std::pair<std::string, bool> describe(std::exception_ptr e) {
  try {
    std::rethrow_exception(e);
  } catch (const InputError& x) {
    return {x.what(), true};
  } catch (const std::bad_alloc&) {
    return {"out of memory", true};
  } catch (const std::exception& x) {
    return {x.what(), false};
  } catch (...) {
    return {"unknown error", false};
  }
}

// The work-estimate grid along the largest axis: a few cells per rank to balance on, few enough
// bricks that reading them stays cheap: each cell is a coarse brick, and a procedural one costs real
// CPU time to generate.
int estimate_cells(int ranks) { return std::clamp(2 * ranks, 8, 64); }

}  // namespace

Distributed::Distributed() {
  int inited = 0;
  MPI_Initialized(&inited);
  if (!inited) {
    int provided = 0;
    MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided);
  }
  MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
  MPI_Comm_size(MPI_COMM_WORLD, &ranks_);
  IceTCommunicator comm = icetCreateMPICommunicator(MPI_COMM_WORLD);
  icet_comm_ = comm;
  IceTContext ctx = icetCreateContext(comm);
  icet_context_ = ctx;
  icetDiagnostics(ICET_DIAG_ERRORS | ICET_DIAG_ROOT_NODE);
  // Premultiplied float RGBA, no depth, blended in a given order (DESIGN.md "Beyond one machine"):
  // the "over" of front-to-back partial sums equals the single ray's sum up to rounding.
  icetSetColorFormat(ICET_IMAGE_COLOR_RGBA_FLOAT);
  icetSetDepthFormat(ICET_IMAGE_DEPTH_NONE);
  icetCompositeMode(ICET_COMPOSITE_MODE_BLEND);
  icetEnable(ICET_ORDERED_COMPOSITE);
  icetDisable(ICET_CORRECT_COLORED_BACKGROUND);  // transparent background: rank 0 adds the scene's once
  icetStrategy(ICET_STRATEGY_SEQUENTIAL);        // one tile: IceT's single-image strategy on it
  icetSingleImageStrategy(ICET_SINGLE_IMAGE_STRATEGY_RADIXK);
  // Identity matrices and the clip-space cube: every rank may cover every pixel (the region's own
  // projection would let IceT skip pixels; the composite is O(pixels) per rank either way).
  icetBoundingBoxd(-1.0, 1.0, -1.0, 1.0, -1.0, 1.0);
  figures_.ranks = ranks_;
}

Distributed::~Distributed() {
  icetDestroyContext(static_cast<IceTContext>(icet_context_));
  icetDestroyMPICommunicator(static_cast<IceTCommunicator>(icet_comm_));
  MPI_Finalize();
}

void Distributed::agree(std::exception_ptr error) {
  int first = error ? rank_ : ranks_;
  MPI_Allreduce(MPI_IN_PLACE, &first, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
  if (first == ranks_) return;
  // The first failing rank sends its message (and whether it is bad input) to rank 0.
  std::string message;
  int input = 1;
  if (rank_ == first) {
    auto [m, in] = describe(error);
    message = m;
    input = in ? 1 : 0;
  }
  if (first != 0) {
    if (rank_ == first) {
      MPI_Send(&input, 1, MPI_INT, 0, 1, MPI_COMM_WORLD);
      MPI_Send(message.data(), int(message.size()), MPI_CHAR, 0, 2, MPI_COMM_WORLD);
    } else if (rank_ == 0) {
      MPI_Status st;
      MPI_Recv(&input, 1, MPI_INT, first, 1, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
      MPI_Probe(first, 2, MPI_COMM_WORLD, &st);
      int n = 0;
      MPI_Get_count(&st, MPI_CHAR, &n);
      message.resize(std::size_t(n));
      MPI_Recv(message.data(), n, MPI_CHAR, first, 2, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
    }
  }
  failed_ = true;
  if (rank_ != 0) throw PeerFailed();
  if (first == 0) std::rethrow_exception(error);
  const std::string what = "rank " + std::to_string(first) + ": " + message;
  if (input) throw InputError("", what);
  throw std::runtime_error(what);
}

void Distributed::leave_together() { MPI_Barrier(MPI_COMM_WORLD); }

int Distributed::status_of_root(int status) {
  MPI_Bcast(&status, 1, MPI_INT, 0, MPI_COMM_WORLD);
  return status;
}

bool Distributed::all(bool value) {
  agree();
  int v = value ? 1 : 0;
  MPI_Allreduce(MPI_IN_PLACE, &v, 1, MPI_INT, MPI_LAND, MPI_COMM_WORLD);
  return v != 0;
}

const KdRegion& Distributed::balance(const VolumeSource& source, const BrickLayout& layout, int block,
                                     const CullParams& cull) {
  const std::uint64_t key = cull_key(cull);
  if (split_valid_ && key == split_key_) return split_.regions[std::size_t(rank_)];
  Timer t;
  const int level = work_level(layout, estimate_cells(ranks_));
  WorkGrid grid;
  std::exception_ptr error;
  try {
    grid = estimate_work(source, layout, level, block, cull, rank_, ranks_);
  } catch (...) {
    error = std::current_exception();
  }
  agree(error);
  MPI_Allreduce(MPI_IN_PLACE, grid.work.data(), int(grid.work.size()), MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
  split_ = split_regions(grid, ranks_);
  split_key_ = key;
  split_valid_ = true;
  figures_.balance_ms = t.ms();
  figures_.estimate_level = level;
  figures_.work_imbalance = split_.max_over_mean_work();
  return split_.regions[std::size_t(rank_)];
}

Frame Distributed::composite(Frame local, const ViewPoint& view) {
  SL_CHECK(split_valid_);
  agree();
  const int w = local.image.width, h = local.image.height;
  const std::size_t n = std::size_t(w) * std::size_t(h);

  // Per-rank figures to rank 0.
  RankFigures mine;
  const Stats& ls = local.stats;
  mine.render_ms = ls.time_ms.total;
  mine.samples = double(ls.samples);
  mine.useful_samples = double(ls.useful_samples);
  mine.rays = double(ls.rays);
  mine.work = split_.regions[std::size_t(rank_)].work;
  mine.resident_mb = ls.cache.resident_mb;
  mine.page_table_bytes = double(ls.cache.page_table_bytes);
  mine.tree_nodes = double(ls.tree_nodes);
  mine.tree_bytes = double(ls.tree_bytes);
  mine.loads = double(ls.cache.loads);
  mine.completeness = ls.cache.completeness;
  mine.bricks_missing = double(ls.cache.bricks_missing);
  mine.failed = double(ls.cache.failed);
  mine.peak_rss_mb = peak_resident_mb();
  static_assert(sizeof(RankFigures) == RankFigures::kFields * sizeof(double), "RankFigures is doubles");
  std::vector<RankFigures> all(root() ? std::size_t(ranks_) : 0);
  MPI_Gather(&mine, RankFigures::kFields, MPI_DOUBLE, all.data(), RankFigures::kFields, MPI_DOUBLE, 0,
             MPI_COMM_WORLD);

  // Wait for the slowest rank here, so the compositing time is IceT's alone.
  Timer wait;
  MPI_Barrier(MPI_COMM_WORLD);
  const double wait_ms = wait.ms();

  Timer t;
  const std::vector<int> order = split_.order(view);
  icetResetTiles();
  icetAddTile(0, 0, w, h, 0);
  icetPhysicalRenderSize(w, h);
  icetCompositeOrder(order.data());
  const IceTDouble identity[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  const IceTFloat transparent[4] = {0, 0, 0, 0};
  static_assert(sizeof(vec4) == 4 * sizeof(float), "Image::rgba is packed float RGBA");
  const IceTImage image =
      icetCompositeImage(local.image.rgba.data(), nullptr, nullptr, identity, identity, transparent);
  const double composite_ms = t.ms();
  IceTDouble bytes = 0;
  icetGetDoublev(ICET_BYTES_SENT, &bytes);

  // The extra channels: summed counts, and the nearest iso hit (no hit: -1). The DVR and labels depth
  // (where the composite's opacity reaches 0.5) does not follow from the ranks' own depths, and is
  // left out rather than approximated (the same on every rank: the mode is).
  Frame out;
  if (root()) out = Frame{Image(w, h), local.stats};
  for (auto& [name, ch] : local.image.channels) {
    const bool depth = name == "depth";
    if (depth && local.stats.mode != to_string(RenderMode::Iso)) continue;
    if (depth) {
      for (float& d : ch) d = d < 0.0f ? INFINITY : d;
    }
    std::vector<float> sum(root() ? n : 0);
    MPI_Reduce(ch.data(), sum.data(), int(n), MPI_FLOAT, depth ? MPI_MIN : MPI_SUM, 0, MPI_COMM_WORLD);
    if (root()) {
      if (depth) {
        for (float& d : sum) d = std::isinf(d) ? -1.0f : d;
      }
      out.image.channels[name] = std::move(sum);
    }
  }
  if (!root()) return out;

  const IceTFloat* c = icetImageGetColorcf(image);
  std::copy(c, c + 4 * n, &out.image.rgba[0].x);
  DistributedFigures& f = figures_;
  f.per_rank = all;
  f.composite_ms = composite_ms;
  f.wait_ms = wait_ms;
  f.bytes_sent = bytes;
  double mx = 0, sum = 0;
  Stats& st = out.stats;
  st.samples = st.rays = st.useful_samples = 0;
  st.cache.resident_mb = 0;
  st.cache.page_table_bytes = 0;
  st.tree_bytes = 0;
  st.cache.loads = st.cache.bricks_missing = st.cache.failed = 0;
  st.tree_nodes = 0;
  for (const RankFigures& r : all) {
    mx = std::max(mx, r.render_ms);
    sum += r.render_ms;
    st.samples += std::uint64_t(r.samples);
    st.useful_samples += std::uint64_t(r.useful_samples);
    st.rays += std::uint64_t(r.rays);
    st.cache.resident_mb += r.resident_mb;
    st.cache.page_table_bytes += std::uint64_t(r.page_table_bytes);
    st.tree_bytes += std::uint64_t(r.tree_bytes);
    st.cache.loads += std::uint64_t(r.loads);
    st.cache.bricks_missing += std::uint64_t(r.bricks_missing);
    st.cache.failed += std::uint64_t(r.failed);
    st.cache.completeness = std::min(st.cache.completeness, r.completeness);
    st.tree_nodes += std::uint64_t(r.tree_nodes);
  }
  f.time_imbalance = sum > 0 ? mx * double(ranks_) / sum : 1.0;
  // The frame as the job sees it: the slowest rank, then the composite.
  st.time_ms.total = mx + composite_ms;
  return out;
}

std::string Distributed::stats_json(const Stats& st) const {
  nlohmann::json js = nlohmann::json::parse(stats_to_json(st));
  const DistributedFigures& f = figures_;
  nlohmann::json d = {{"ranks", f.ranks},
                      {"composite_ms", f.composite_ms},
                      {"wait_ms", f.wait_ms},
                      {"composite_bytes_sent_rank0", f.bytes_sent},
                      {"work_imbalance", f.work_imbalance},
                      {"time_imbalance", f.time_imbalance},
                      {"balance_ms", f.balance_ms},
                      {"estimate_level", f.estimate_level}};
  d["per_rank"] = nlohmann::json::array();
  for (std::size_t i = 0; i < f.per_rank.size(); ++i) {
    const RankFigures& r = f.per_rank[i];
    const KdRegion& g = split_.regions[i];
    d["per_rank"].push_back({{"rank", int(i)},
                             {"region_cells_lo", {g.lo.x, g.lo.y, g.lo.z}},
                             {"region_cells_hi", {g.hi.x, g.hi.y, g.hi.z}},
                             {"render_ms", r.render_ms},
                             {"samples", r.samples},
                             {"useful_samples", r.useful_samples},
                             {"rays", r.rays},
                             {"work", r.work},
                             {"resident_mb", r.resident_mb},
                             {"page_table_bytes", r.page_table_bytes},
                             {"tree_nodes", r.tree_nodes},
                             {"tree_bytes", r.tree_bytes},
                             {"loads", r.loads},
                             {"completeness", r.completeness},
                             {"peak_rss_mb", r.peak_rss_mb}});
  }
  js["distributed"] = d;
  return js.dump(2);
}

std::string Distributed::summary() const {
  const DistributedFigures& f = figures_;
  double rss = 0, cache = 0;
  for (const RankFigures& r : f.per_rank) {
    rss = std::max(rss, r.peak_rss_mb);
    cache = std::max(cache, r.resident_mb);
  }
  char buf[320];
  std::snprintf(buf, sizeof buf,
                "distributed: %d ranks, composite %.1f ms, load imbalance %.2f (time) %.2f (work), per rank at most "
                "%.0f MB peak RSS, %.1f MB cache",
                f.ranks, f.composite_ms, f.time_imbalance, f.work_imbalance, rss, cache);
  return buf;
}

int run_distributed(const std::function<int(Distributed&)>& body) {
  Distributed d;
  // The other ranks' summaries and tables would repeat rank 0's (their stderr stays: warnings).
  if (!d.root() && !std::freopen("/dev/null", "w", stdout)) std::fclose(stdout);
  try {
    const int rc = body(d);
    d.agree();  // the last step (rank 0's outputs) may fail too
    return d.status_of_root(rc);
  } catch (...) {
    // Failed in an agreement: rank 0 reports it, the others leave quietly.
    std::exception_ptr error = std::current_exception();
    if (!d.failed()) {
      try {
        d.agree(error);
      } catch (...) {
        error = std::current_exception();
      }
    }
    // Rank 0 prints before anyone leaves: mpirun aborts the job when a rank exits non-zero, which
    // would kill rank 0 before its line reached stderr.
    int rc = 1;
    if (d.root()) {
      rc = report_error(error);
      std::fflush(stderr);
    }
    d.leave_together();
    return rc;
  }
}

}  // namespace sl::app
