// Depth passes: a pinned level (--lod N) whose working set does not fit the cache still converges to
// the exact image of that level, in more frames. The view's rays are cut into depth ranges along t,
// front to back; a pass casts only the samples of its range (SkipInputs::pass_t0/pass_t1), starting
// each ray from the state the last pass left (its RayAccum: colour, opacity, the iso bracket, ERT),
// and is repeated over frames until it settles with every sample at its level. Then its states are
// committed and the next range begins; bricks of the ranges behind are no longer used and the LRU
// cache lets them go. A range that settles short of complete (its bricks still do not fit) is halved
// and cast again from the same committed states. The passes partition every ray's samples and carry
// its state exactly, so the last pass's image is the one-pass image, bit for bit.
//
// Passes start only when a frame at a pinned level has settled incomplete (nothing more fits), and
// end when anything the image depends on changes (camera, image size, casting settings, transfer
// function or labels). They run where the cast runs on the host (the CPU device and its simulated
// stand-in); the CUDA device renders such a view incomplete, as before. Memory: two RayAccum per
// pixel (the committed states and the frame's), 88 bytes per pixel (22 MiB at 512²), reported as
// CacheStats::depth_pass_bytes.
#pragma once

#include <cstdint>
#include <vector>

#include "core/cast/raycast.h"
#include "core/frame/frame.h"
#include "core/scene/camera.h"

namespace sl {

class DepthPasses {
 public:
  // What the passes' image depends on besides the resident bricks.
  struct View {
    Camera camera;
    RenderSettings settings;  // image size and every casting setting
    std::uint64_t cull_key = 0;  // transfer function, labels, mode (LazyOccupancy::cull_key)

    bool operator==(const View&) const = default;
  };

  // Before the frame's cast: ends the passes when the view changed.
  void begin_frame(const View& view);
  // The cut of the frame's rays and their states (SkipInputs::pass_t0/pass_t1/rays); unchanged when
  // no passes run.
  void apply(float& t0, float& t1, RayAccum*& rays);

  // After the frame. `settled`: nothing more to load or resolve (Convergence); `complete`: every
  // sample at its level (`completeness`: the share that is); `can_split`: passes may help (a pinned
  // level, a device that casts on the host, no brick failed). `t_near`/`t_far`: the view's range of
  // t over the volume box; `min_width`: the thinnest range worth a pass (a quarter of a brick).
  // `working_share`: the view's working set over the cache (> 1 when it does not fit; 0 unknown).
  // Returns true when the frame changed the passes (the caller restarts its convergence).
  bool end_frame(bool settled, bool complete, double completeness, bool can_split, float t_near, float t_far,
                 float min_width, double working_share);

  bool running() const { return !bounds_.empty(); }
  // Passes running and the last one not yet settled complete: the view is not converged.
  bool in_progress() const { return running() && !finished_; }
  int count() const { return running() ? int(bounds_.size()) - 1 : 0; }
  int current() const { return pass_; }
  // The least completeness a pass settled at (1 when every pass was complete).
  double completeness() const { return completeness_; }
  std::uint64_t bytes() const {
    return std::uint64_t(committed_.capacity() + frame_.capacity()) * sizeof(RayAccum);
  }

 private:
  void reset();

  View view_;
  bool have_view_ = false;
  std::vector<float> bounds_;  // pass i is [bounds_[i], bounds_[i + 1]); first 0, last +inf
  int pass_ = 0;
  bool finished_ = false;              // the last pass settled complete: the frames repeat it
  std::vector<RayAccum> committed_;    // the rays' states before pass_
  std::vector<RayAccum> frame_;        // the frame's states (a copy of committed_, then cast)
  float t_near_ = 0.0f, t_far_ = 0.0f;  // the view's t range, fixed when the passes start
  double completeness_ = 1.0;
};

// The range of t over which the rays of `gen` can meet the box [lo, hi]: from the box's nearest point
// (0 inside it) to its farthest corner; along the view axis for an orthographic camera.
void view_depth_range(const RayGenerator& gen, const vec3& lo, const vec3& hi, float& t_near, float& t_far);

}  // namespace sl
