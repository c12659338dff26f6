// Loading what a frame needs (volume, labels, transfer function, camera) from the command line's
// scene options (registered with the other render options, apps/render_options.h), shared by render,
// bench and view.
#pragma once

#include <cstddef>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cache/volume_source.h"
#include "core/scene/camera.h"
#include "core/scene/labels.h"
#include "core/scene/transfer_function.h"
#include "core/scene/volume.h"

namespace sl {
class CountingByteStore;
}

namespace sl::app {

struct SceneOptions {
  std::string volume;   // file, store directory or URL; empty = built-in neurites
  std::string labels;   // optional label volume (file, store or URL)
  std::string tf;       // transfer-function JSON; empty = default for the data
  std::string camera;   // camera JSON; empty = default view
  std::string enable;   // enabled-label spec; empty = no label mask
  std::string inject_faults;  // out of core: a fault spec (cache/testing/fault_injection.h); empty = none
  std::string disk_cache;          // --disk-cache: on-disk cache of remote store objects; empty = none
  std::size_t disk_cache_mb = 0;   // its bound (0: the default, 1024)
  std::string pyramid;             // --pyramid: mean or max; empty = the source's default (scene_loader.cpp)
};

// A scene whose data may also be read out of core: a volume in memory (rendered in core, or through
// the brick cache when `out_of_core`), or a procedural source that exists only as bricks (always out
// of core, DESIGN.md "Virtual memory"). Procedural sources have their own hashed label ids: no
// --labels/--enable.
struct SourceScene {
  std::string name;
  VolumeDesc desc;
  std::shared_ptr<const Volume> volume;  // null for a procedural source
  std::shared_ptr<const Volume> labels;  // null without a label volume
  std::uint32_t label_count = 0;
  TransferFunction tf;
  Camera camera;
  std::optional<LabelSet> enabled;
  std::shared_ptr<const VolumeSource> source;  // set when rendering out of core
  bool labelled = false;  // a label volume whose ids --enable and labels mode can name
  // The stores a streamed precomputed volume (and its labels) read through, counting requests and bytes
  // for bench's `store` line; empty otherwise (null entries are skipped).
  std::vector<std::shared_ptr<const CountingByteStore>> store_io;
  bool out_of_core() const { return source != nullptr; }
};
// `labels_shown`: something may show the labels (labels mode, an --enable mask, or a viewer that can
// switch to them). Without it, or without labels the scene can name (a procedural volume's are hashed),
// the out-of-core source is given without its labels (without_labels): the brick cache then holds
// intensity only, five times as many u8 bricks as with u32 labels beside them.
SourceScene load_source_scene(const SceneOptions& o, bool out_of_core, bool labels_shown);

// Half of this machine's physical memory: what one input may take (0 when unknown).
std::uint64_t in_memory_limit();
// Refuses, before any allocation, data that would take more than half of this machine's memory:
// InputError(who, "WHAT needs N MiB in memory, more than half of this machine's M MiB" + hint).
void check_fits_in_memory(std::uint64_t bytes, const std::string& who, const std::string& what,
                          const std::string& hint = {});

// Built-in data set: neurites, generated in memory (no file needed).
constexpr int kBuiltinSize = 256;

}  // namespace sl::app
