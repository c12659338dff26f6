// `--distributed` (DESIGN.md "Beyond one machine"): sort-last rendering under mpirun. Every rank opens
// the same volume source and runs the ordinary out-of-core renderer on its region of a k-d split of
// the brick grid (core/frame/kd_regions.h), balanced on the estimated work (cache/out_of_core/work_estimate.h);
// rays sample the global per-ray grid clipped to the region (core/cast/sample_clip.h); IceT composites
// the premultiplied float RGBA in the regions' front-to-back order for the camera, and rank 0 writes
// the outputs. The thin MPI + IceT layer; built only with SL_MPI (apps/CMakeLists.txt).
//
// Early ray termination (--ert) cannot be exact across ranks: a rank stops its rays when its own
// partial opacity reaches the threshold, not the composited one, so a rank behind an opaque one
// still casts, and the composite differs from the single process by at most the 1 - threshold
// (1%) of light the single process drops after termination.
#pragma once

#include <cstdint>
#include <exception>
#include <functional>
#include <string>
#include <vector>

#include "cache/brick.h"
#include "cache/volume_source.h"
#include "core/occupancy/culling.h"
#include "core/frame/frame.h"
#include "core/frame/kd_regions.h"
#include "core/lists/visibility_order.h"

namespace sl::app {

// What one rank contributed to a composited frame (rank 0 gathers them).
struct RankFigures {
  double render_ms = 0;      // the rank's own frame (metadata, tree, lists, cast)
  double samples = 0;
  double useful_samples = 0;
  double rays = 0;
  double work = 0;           // the split's estimate for its region
  double resident_mb = 0;    // brick cache in use
  double page_table_bytes = 0;
  double tree_nodes = 0;
  double tree_bytes = 0;
  double loads = 0;
  double completeness = 1;
  double bricks_missing = 0;
  double failed = 0;
  double peak_rss_mb = 0;    // the process's high-water mark (VmHWM)
  static constexpr int kFields = 14;
};

// The distributed figures of the last composited frame (rank 0).
struct DistributedFigures {
  int ranks = 1;
  double composite_ms = 0;   // IceT's compositing (after every rank finished rendering)
  double wait_ms = 0;        // rank 0 waiting for the slowest rank before compositing
  double bytes_sent = 0;     // by rank 0 in the composite (IceT)
  double work_imbalance = 1; // max / mean of the split's work estimate
  double time_imbalance = 1; // max / mean of the ranks' render times
  double balance_ms = 0;     // the work estimate and split (when they were last made)
  int estimate_level = 0;    // pyramid level the work was estimated on
  std::vector<RankFigures> per_rank;
};

class Distributed {
 public:
  // MPI_Init (MPI_THREAD_FUNNELED: only the main thread calls MPI) and an IceT context on
  // MPI_COMM_WORLD. MPI_Finalize at destruction.
  Distributed();
  ~Distributed();
  Distributed(const Distributed&) = delete;
  Distributed& operator=(const Distributed&) = delete;

  int rank() const { return rank_; }
  int ranks() const { return ranks_; }
  bool root() const { return rank_ == 0; }
  // An agree() found a failure (and threw).
  bool failed() const { return failed_; }

  // Collective: every rank calls it at the same point, with its failure (null: none). When any rank
  // failed, rank 0 throws the first failing rank's error (prefixed "rank N: " unless it is rank 0's
  // own) and the other ranks throw PeerFailed; so every rank leaves, and one line is printed.
  void agree(std::exception_ptr error = nullptr);
  // Collective: a barrier, after rank 0 has reported a failure and before any rank exits.
  void leave_together();
  // Collective: `value` holds on every rank.
  bool all(bool value);
  // Collective: rank 0's exit status, on every rank. Rank 0 decides it from the composited frame
  // (incomplete: 4; --strict with failed bricks: 1), so every rank exits with the same status.
  int status_of_root(int status);

  // This rank's region of the work-balanced split of the scene under `cull`: each rank estimates a
  // share of the coarse bricks, the grids are summed (MPI_Allreduce) and every rank splits the same
  // grid. Re-balanced only when the culling inputs (their cull_key) change.
  const KdRegion& balance(const VolumeSource& source, const BrickLayout& layout, int block, const CullParams& cull);

  // Collective: composites the ranks' frames (premultiplied RGBA, transparent background) in the
  // regions' front-to-back order for `view`. Rank 0 gets the image, the summed channels (samples,
  // depth complexity; iso depth: the nearest hit) and summed counters; the other ranks an empty frame.
  Frame composite(Frame local, const ViewPoint& view);

  const DistributedFigures& figures() const { return figures_; }
  // stats_to_json(st) with a "distributed" object: the figures above and one entry per rank.
  std::string stats_json(const Stats& st) const;
  // One line for people: ranks, compositing, imbalance, memory per rank.
  std::string summary() const;

 private:
  int rank_ = 0, ranks_ = 1;
  void* icet_comm_ = nullptr;  // IceTCommunicator
  void* icet_context_ = nullptr;  // IceTContext
  KdSplit split_;
  std::uint64_t split_key_ = 0;
  bool split_valid_ = false;
  bool failed_ = false;
  DistributedFigures figures_;
};

// Thrown on ranks other than 0 when some rank failed: rank 0 reports the error.
struct PeerFailed : std::exception {
  const char* what() const noexcept override { return "another rank failed"; }
};

// Runs body(d) on every rank of the MPI job (standard output only on rank 0). A rank that throws joins the next
// agree() of the others with its error (every collective step of Distributed starts with one), so all ranks leave
// without a hang; rank 0 prints the first failing rank's error once (report_error), then every rank meets at a
// barrier and returns non-zero (rank 0 its error's exit code, the others 1), so mpirun's abort on a non-zero exit
// cannot cut rank 0 off before its line is out. When body returns, every rank returns rank 0's status. A brick
// that fails to load is no failure here: each rank renders it as missing with the single process's warning.
int run_distributed(const std::function<int(Distributed&)>& body);

}  // namespace sl::app
