#include "apps/viewer/render_worker.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <exception>
#include <future>

namespace sl::viewer {

std::vector<std::uint8_t> to_display_rgba8(const Image& img) {
  // A 4096-entry table: three pow() per pixel would cost as much as a cheap frame's ray casting.
  static const std::array<std::uint8_t, 4096> lut = [] {
    std::array<std::uint8_t, 4096> t{};
    for (std::size_t i = 0; i < t.size(); ++i) {
      t[i] = std::uint8_t(std::lround(255.0f * linear_to_srgb(float(i) / float(t.size() - 1))));
    }
    return t;
  }();
  std::vector<std::uint8_t> out(img.rgba.size() * 4);
  for (std::size_t i = 0; i < img.rgba.size(); ++i) {
    const vec4& c = img.rgba[i];
    for (int k = 0; k < 3; ++k) {
      const float x = std::isfinite(c[k]) ? std::clamp(c[k], 0.0f, 1.0f) : 0.0f;
      out[i * 4 + std::size_t(k)] = lut[std::size_t(x * float(lut.size() - 1) + 0.5f)];
    }
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
    r.preview = job.preview;
    r.camera = job.camera;
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
