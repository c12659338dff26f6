// Rendering off the UI thread: the viewer submits the frame it wants, a worker thread renders it and
// converts it for display, and the UI polls for the result. A newer job replaces one not yet started
// (latest wins), so a long frame never blocks input and dragging never builds a queue. The worker
// holds the renderer, which keeps its cached metadata, tree and lists between frames.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "core/frame/frame.h"

namespace sl::viewer {

struct RenderJob {
  std::uint64_t id = 0;
  Camera camera;
  RenderSettings settings;
  // Snapshots the job owns: the UI keeps editing its own copies while the worker renders.
  std::shared_ptr<const TransferFunction> tf;
  std::shared_ptr<const LabelSet> enabled;  // null: no label mask
  int level = 0;  // progressive level (apps/viewer/progressive.h): 0 full resolution, else coarse
};

struct RenderResult {
  std::uint64_t id = 0;
  int level = 0;
  Camera camera;  // what was rendered: label picking casts through this view
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> rgba8;  // sRGB over black, row 0 at the top, alpha 255
  Stats stats;
  double worker_ms = 0.0;  // wall time of the render and the conversion for display
  std::string error;  // non-empty when the frame failed; the UI shows it and keeps the last image
};

// What the PNG of a frame shows (DESIGN.md "Rendering conventions": premultiplied colour over black,
// sRGB-encoded), as 8-bit RGBA for a texture: byte for byte the PNG's values (write_png), so a
// full-resolution frame on screen is the image `render` writes.
std::vector<std::uint8_t> to_display_rgba8(const Image& img);

class RenderWorker {
 public:
  using RenderFn = std::function<Frame(const Scene&, const RenderSettings&)>;

  // `make_renderer` runs on the worker thread, which then owns what it returns (the renderer and its
  // caches, a GL context for `--lists gl`: current on the thread that made it) and destroys it there
  // when it ends. The constructor waits for it and rethrows what it throws (InputError for settings
  // the renderer refuses), so a bad setting fails before the viewer opens a window.
  // `volume` and `labels` (may be null) must outlive the worker; they are only read. `on_done` runs on
  // the worker thread after each frame (the viewer wakes its event loop with it).
  RenderWorker(const Volume* volume, const Volume* labels, std::function<RenderFn()> make_renderer,
               std::function<void()> on_done = {});
  ~RenderWorker();  // finishes the frame in progress, drops a queued one, joins
  RenderWorker(const RenderWorker&) = delete;
  RenderWorker& operator=(const RenderWorker&) = delete;

  void submit(RenderJob job);
  // The newest finished frame since the last call (older unread ones are dropped).
  std::optional<RenderResult> take();
  bool idle() const;  // nothing queued, nothing rendering
  void wait_idle();   // for scripted runs (--screenshot) and tests

 private:
  void run();

  const Volume* volume_;
  const Volume* labels_;
  RenderFn render_;  // made, used and destroyed on the worker thread
  std::function<void()> on_done_;
  mutable std::mutex mutex_;
  std::condition_variable wake_, done_;
  std::optional<RenderJob> queued_;
  std::optional<RenderResult> finished_;
  bool busy_ = false;
  bool stop_ = false;
  std::thread thread_;
};

}  // namespace sl::viewer
