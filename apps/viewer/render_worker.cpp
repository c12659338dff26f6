#include "apps/viewer/render_worker.h"

#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <exception>
#include <future>

namespace sl::viewer {

namespace {

// The PNG writer's encoding, lround(255 * linear_to_srgb(x)), without a pow per channel (three per
// pixel would cost as much as a cheap frame's ray casting). The encoding is monotonic in x, so it is
// fixed by the 255 values where the code steps up; they are found once by bisection over the floats in
// [0, 1] (whose bit patterns are ordered as their values). A 4096-entry table of the codes at i/4096
// gives a lower bound that the steps then correct, so the result is the PNG's byte for every float.
class SrgbEncoder {
 public:
  SrgbEncoder() {
    const std::uint32_t one = std::bit_cast<std::uint32_t>(1.0f);
    step_[0] = 0.0f;
    for (int k = 1; k < 256; ++k) {
      std::uint32_t lo = 0, hi = one;  // the first float in [lo, hi] whose code reaches k
      while (lo < hi) {
        const std::uint32_t mid = lo + (hi - lo) / 2;
        if (code(std::bit_cast<float>(mid)) >= k) {
          hi = mid;
        } else {
          lo = mid + 1;
        }
      }
      step_[std::size_t(k)] = std::bit_cast<float>(lo);
    }
    for (std::size_t i = 0; i < guess_.size(); ++i) guess_[i] = std::uint8_t(code(float(i) / kGuessBins));
  }

  std::uint8_t operator()(float x) const {
    if (!(x > 0.0f) || !std::isfinite(x)) return 0;
    if (x >= 1.0f) return 255;
    // x * 4096 is exact (a power of two), so the bin's left end is <= x and its code a lower bound.
    int k = guess_[std::size_t(x * kGuessBins)];
    while (k < 255 && x >= step_[std::size_t(k) + 1]) ++k;
    return std::uint8_t(k);
  }

 private:
  static constexpr float kGuessBins = 4096.0f;
  static int code(float x) { return int(std::lround(255.0f * linear_to_srgb(x))); }

  std::array<float, 256> step_{};                  // step_[k]: the least x with code(x) >= k
  std::array<std::uint8_t, 4097> guess_{};         // code(i / 4096)
};

}  // namespace

std::vector<std::uint8_t> to_display_rgba8(const Image& img) {
  static const SrgbEncoder encode;
  std::vector<std::uint8_t> out(img.rgba.size() * 4);
  for (std::size_t i = 0; i < img.rgba.size(); ++i) {
    const vec4& c = img.rgba[i];
    for (int k = 0; k < 3; ++k) out[i * 4 + std::size_t(k)] = encode(c[k]);
    out[i * 4 + 3] = 255;
  }
  return out;
}

RenderWorker::RenderWorker(const Volume* volume, const Volume* labels, std::function<RenderFn()> make_renderer,
                           std::function<void()> on_done)
    : volume_(volume), labels_(labels), on_done_(std::move(on_done)) {
  std::promise<void> made;
  std::future<void> ready = made.get_future();
  thread_ = std::thread([this, make = std::move(make_renderer), made = std::move(made)]() mutable {
    try {
      render_ = make();
    } catch (...) {
      made.set_exception(std::current_exception());
      return;
    }
    made.set_value();
    run();
    render_ = nullptr;  // the renderer ends on the thread that made it
  });
  try {
    ready.get();
  } catch (...) {
    thread_.join();
    throw;
  }
}

RenderWorker::~RenderWorker() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
    queued_.reset();
  }
  wake_.notify_all();
  thread_.join();
}

void RenderWorker::submit(RenderJob job) {
  {
    std::lock_guard lock(mutex_);
    queued_ = std::move(job);
  }
  wake_.notify_one();
}

std::optional<RenderResult> RenderWorker::take() {
  std::lock_guard lock(mutex_);
  std::optional<RenderResult> r = std::move(finished_);
  finished_.reset();
  return r;
}

bool RenderWorker::idle() const {
  std::lock_guard lock(mutex_);
  return !busy_ && !queued_;
}

void RenderWorker::wait_idle() {
  std::unique_lock lock(mutex_);
  done_.wait(lock, [this] { return !busy_ && !queued_; });
}

void RenderWorker::run() {
  for (;;) {
    RenderJob job;
    {
      std::unique_lock lock(mutex_);
      wake_.wait(lock, [this] { return stop_ || queued_.has_value(); });
      if (stop_) return;
      job = std::move(*queued_);
      queued_.reset();
      busy_ = true;
    }
    RenderResult r;
    r.id = job.id;
    r.level = job.level;
    r.camera = job.camera;
    const auto start = std::chrono::steady_clock::now();
    try {
      Scene scene;
      scene.volume = volume_;
      scene.labels = labels_;
      scene.tf = job.tf.get();
      scene.enabled = job.enabled.get();
      scene.camera = job.camera;
      Frame f = render_(scene, job.settings);
      r.width = f.image.width;
      r.height = f.image.height;
      r.rgba8 = to_display_rgba8(f.image);
      r.stats = std::move(f.stats);
      r.worker_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    } catch (const std::exception& e) {
      // A bad setting (e.g. a degenerate camera) must not end the viewer: report it, keep going.
      r.error = e.what();
    }
    {
      std::lock_guard lock(mutex_);
      finished_ = std::move(r);
      busy_ = false;
    }
    done_.notify_all();
    if (on_done_) on_done_();
  }
}

}  // namespace sl::viewer
