// What the viewer shows and which renderer draws it: a volume in memory (rendered in core by the
// chosen backend, or out of core through the brick cache with --cache-mb), or a procedural source
// that exists only as bricks (always out of core, DESIGN.md §4).
#pragma once

#include <memory>
#include <optional>
#include <string>

#include "apps/backend.h"
#include "apps/scene_loader.h"
#include "apps/viewer/render_worker.h"
#include "apps/viewer/ui/viewer.h"
#include "cache/volume_source.h"

namespace sl::viewer {

using ViewerScene = app::SourceScene;

// Loads the data, transfer function and camera; InputError for bad files or options.
ViewerScene load_viewer_scene(const ViewerOptions& o);

// The function the render worker calls: owns the renderer (in-core FrameRenderer or the out-of-core
// renderer with its cache and loader threads), which keeps its caches from frame to frame. Throws
// InputError for settings the renderer refuses (e.g. a cache too small for one brick per level).
RenderWorker::RenderFn make_render_fn(const ViewerScene& s, const ViewerOptions& o, app::Backend backend);

}  // namespace sl::viewer
