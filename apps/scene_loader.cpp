#include "apps/scene_loader.h"

#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <regex>

#include "cache/testing/fault_injection.h"
#include "core/scene/generate.h"
#include "cache/synthetic/procedural_neurites.h"
#include "cache/stores/counting_byte_store.h"
#include "cache/stores/disk_cache.h"
#include "cache/formats/nrrd/nrrd.h"
#include "cache/formats/precomputed/source.h"
#include "cache/stores/store_kind.h"
#include "cache/stores/store_url.h"
#include "cache/formats/volume_file.h"
#include "cache/formats/zarr/meta.h"
#include "cache/formats/zarr/source.h"
#include "core/util/error.h"

#include <unistd.h>

namespace sl::app {

namespace {

// Without --tf the default ramp spans the volume's finite values. A float volume with no finite value,
// or whose values span more than a float holds, has nothing such a ramp could map: that is the
// volume's problem, named as such.
TransferFunction default_tf_for_range(vec2 r, const std::string& volume) {
  if (!(r.x <= r.y)) {
    throw InputError(volume, "no finite values (all NaN or infinite): no default transfer function; give --tf");
  }
  if (!std::isfinite(r.y - r.x)) {
    char buf[160];
    std::snprintf(buf, sizeof buf, "value range [%g, %g] overflows a float (its width is beyond %g); give --tf",
                  double(r.x), double(r.y), double(std::numeric_limits<float>::max()));
    throw InputError(volume, buf);
  }
  return default_transfer_function(r.x, r.y > r.x ? r.y : r.x + 1.0f);
}

std::string dims_text(const VolumeDesc& d) {
  return std::to_string(d.dims.x) + "x" + std::to_string(d.dims.y) + "x" + std::to_string(d.dims.z) + " " +
         to_string(d.type);
}

// "builtin:KIND[:XxYxZ[:SEED]]": a generated data set held in memory (no file). Errors name the spec.
GeneratedVolume load_builtin(const std::string& spec) {
  static const std::regex re("^builtin:([a-z]+)(?::([0-9]{1,5})x([0-9]{1,5})x([0-9]{1,5}))?(?::([0-9]{1,9}))?$");
  std::smatch m;
  if (!std::regex_match(spec, m, re)) {
    throw InputError(spec, "expected builtin:KIND[:XxYxZ[:SEED]], e.g. builtin:neurites:512x512x512");
  }
  const ivec3 dims = m[2].matched ? ivec3(std::stoi(m[2]), std::stoi(m[3]), std::stoi(m[4])) : ivec3(kBuiltinSize);
  const std::uint32_t seed = m[5].matched ? std::uint32_t(std::stoul(m[5])) : 1u;
  try {
    check_fits_in_memory(generated_bytes(m[1], dims), spec, "the generated volume",
                         "; try procedural:neurites:XxYxZ, which streams");
    return generate_volume(m[1], dims, seed);
  } catch (const InputError& e) {
    if (e.file() != "gen") throw;
    throw InputError(spec, e.reason());
  }
}

// A volume file (NRRD, NIfTI-1, TIFF stack), or level 0 of an OME-Zarr store or a Neuroglancer
// precomputed volume read whole (in core), refused from its header when it would not fit in memory, with
// the hint to stream it instead.
Volume read_volume_file(const std::string& given, bool store_labels = false) {
  const StoreLocation store = recognise_store(given);
  const std::string& path = store.path;
  if (store.kind == StoreKind::Precomputed) {
    const VolumeDesc d = read_precomputed_desc(path);
    check_fits_in_memory(d.byte_size(), path, "scale 0 (" + dims_text(d) + ")", "; render it out of core with --cache-mb");
    return read_precomputed_volume(path);
  }
  if (store.kind != StoreKind::Zarr) {
    const VolumeDesc d = read_volume_file_desc(path);
    check_fits_in_memory(d.byte_size(), path, dims_text(d),
                         "; convert it with `sparseleap ingest` and render the store out of core (--cache-mb)");
    return sl::read_volume_file(path);
  }
  const zarr::StoreInfo info = zarr::open_store(path);
  const VolumeDesc& d = store_labels && info.labels ? info.labels->desc : info.image.desc;
  check_fits_in_memory(d.byte_size(), path, "level 0 (" + dims_text(d) + ")", "; render it out of core with --cache-mb");
  return read_zarr_volume(path, store_labels);
}

// A scene held in memory (in core, or out of core from memory).
struct LoadedScene {
  Volume volume;
  Volume labels;  // empty() if none
  std::uint32_t label_count = 0;
  TransferFunction tf;
  Camera camera;
  std::optional<LabelSet> enabled;
  std::string name;  // what was loaded, for messages
};

LoadedScene load_scene(const SceneOptions& o) {
  LoadedScene s;
  if (o.volume.empty() || o.volume.rfind("builtin:", 0) == 0) {
    const std::string spec = o.volume.empty() ? "builtin:neurites" : o.volume;
    GeneratedVolume g = load_builtin(spec);
    s.volume = std::move(g.intensity);
    s.labels = std::move(g.labels);
    s.label_count = g.label_count;
    s.name = spec;
  } else {
    s.volume = read_volume_file(o.volume);
    s.name = o.volume;
    const StoreLocation store = recognise_store(o.volume);
    if (o.labels.empty() && store.kind == StoreKind::Zarr && zarr::open_store(store.path).labels) {
      s.labels = read_volume_file(o.volume, true);
    }
  }
  if (!o.labels.empty()) {
    s.labels = read_volume_file(o.labels);
    if (s.labels.dims() != s.volume.dims()) {
      throw InputError(o.labels, "label volume dims differ from the intensity volume's");
    }
    if (s.labels.type() == VoxelType::F32) throw InputError(o.labels, "label volume must be of an integer type");
    s.label_count = 0;
  }
  if (!s.labels.empty() && s.label_count == 0) s.label_count = max_label(s.labels);
  check_label_table(s.label_count, o.labels.empty() ? s.name : o.labels);

  if (!o.tf.empty()) {
    s.tf = load_transfer_function(o.tf);
  } else if (s.volume.type() == VoxelType::U8) {
    s.tf = default_transfer_function(0.0f, 255.0f);
  } else {
    s.tf = default_tf_for_range(value_range(s.volume), s.name);
  }
  s.camera = o.camera.empty() ? default_camera(s.volume.desc().extent()) : load_camera(o.camera);
  if (!o.enable.empty()) {
    if (s.labels.empty()) throw InputError("--enable", "needs a label volume (--labels)");
    s.enabled = parse_enable_spec(o.enable, s.label_count);
  }
  return s;
}

}  // namespace

std::uint64_t in_memory_limit() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGESIZE);
  return pages > 0 && page > 0 ? std::uint64_t(pages) * std::uint64_t(page) / 2 : 0;
}

void check_fits_in_memory(std::uint64_t bytes, const std::string& who, const std::string& what,
                          const std::string& hint) {
  const std::uint64_t limit = in_memory_limit();
  if (limit > 0 && bytes > limit) {
    throw InputError(who, what + " needs " + std::to_string((bytes + (1u << 20) - 1) >> 20) +
                              " MiB in memory, more than half of this machine's " + std::to_string((2 * limit) >> 20) +
                              " MiB" + hint);
  }
}

namespace {

// A chunked store's source (ZarrVolumeSource, PrecomputedVolumeSource) and what the scene takes from it.
template <class Source> void fill_store_scene(SourceScene& s, std::shared_ptr<Source> src, const SceneOptions& o) {
  s.source = src;
  s.name = src->name();
  s.desc = src->desc();
  s.label_count = src->max_label();
  check_label_table(s.label_count, o.labels.empty() ? o.volume : o.labels);
  s.labelled = src->has_labels();
  if (!o.tf.empty()) {
    s.tf = load_transfer_function(o.tf);
  } else if (s.desc.type == VoxelType::U8) {
    s.tf = default_transfer_function(0.0f, 255.0f);
  } else {
    s.tf = default_tf_for_range(src->value_range_estimate(), o.volume);
  }
  s.camera = o.camera.empty() ? default_camera(s.desc.extent()) : load_camera(o.camera);
  if (!o.enable.empty()) {
    if (!src->has_labels()) throw InputError("--enable", "needs a label volume (the store's labels/ or --labels)");
    s.enabled = parse_enable_spec(o.enable, s.label_count);
  }
}

SourceScene open_source_scene(const SceneOptions& o, bool out_of_core) {
  // Remote stores opened from here on read through the disk cache (cache/stores/store_url.h).
  set_disk_cache(o.disk_cache.empty() ? nullptr
                                      : std::make_shared<DiskCache>(o.disk_cache, std::uint64_t(o.disk_cache_mb > 0 ? o.disk_cache_mb : 1024) << 20));
  SourceScene s;
  const StoreLocation store = recognise_store(o.volume);
  if (out_of_core && store.kind != StoreKind::None) {
    // A chunked store streams chunk by chunk through the brick loader (DESIGN.md "Virtual memory").
    const StoreLocation labels = recognise_store(o.labels);
    if (!o.labels.empty() && labels.kind != store.kind) {
      throw InputError("--labels", store.kind == StoreKind::Zarr
                                       ? "a .zarr volume rendered out of core takes its labels from a .zarr store"
                                       : "a precomputed volume rendered out of core takes its labels from a precomputed volume");
    }
    if (store.kind == StoreKind::Zarr) {
      const auto pyramid = o.pyramid.empty() ? std::nullopt : std::optional(parse_pyramid_kind(o.pyramid, "--pyramid"));
      fill_store_scene(s, std::make_shared<ZarrVolumeSource>(store.path, labels.path, pyramid), o);
    } else {
      if (o.pyramid == "max") throw InputError(store.path, "a precomputed volume has no max levels for --pyramid max (use mean)");
      auto bytes = std::make_shared<CountingByteStore>(open_byte_store(store.path));
      auto label_bytes = o.labels.empty() ? nullptr : std::make_shared<CountingByteStore>(open_byte_store(labels.path));
      fill_store_scene(s, std::make_shared<PrecomputedVolumeSource>(bytes, store.path, label_bytes, labels.path), o);
      s.store_io = {bytes, label_bytes};
    }
    return s;
  }
  if (is_procedural_spec(o.volume)) {
    if (!o.labels.empty()) throw InputError("--labels", "a procedural volume has its own labels");
    if (!o.enable.empty()) {
      throw InputError("--enable", "label subsets of procedural volumes are not supported (their ids are hashed)");
    }
    // Thin neurites average away at coarse mean levels: the max pyramid keeps them in the overview.
    s.source = parse_volume_spec(o.volume, o.pyramid.empty() ? PyramidKind::Max : parse_pyramid_kind(o.pyramid, "--pyramid"));
    s.name = o.volume;
    s.desc = s.source->desc();
    s.tf = o.tf.empty() ? default_transfer_function(0.0f, 255.0f) : load_transfer_function(o.tf);
    s.camera = o.camera.empty() ? default_camera(s.desc.extent()) : load_camera(o.camera);
    return s;
  }
  LoadedScene ls = load_scene(o);
  s.name = ls.name;
  s.desc = ls.volume.desc();
  s.label_count = ls.label_count;
  s.tf = std::move(ls.tf);
  s.camera = ls.camera;
  s.enabled = std::move(ls.enabled);
  s.volume = std::make_shared<const Volume>(std::move(ls.volume));
  if (!ls.labels.empty()) s.labels = std::make_shared<const Volume>(std::move(ls.labels));
  s.labelled = s.labels != nullptr;
  // Mean unless asked: files held in memory are the dense scans and test sets whose overviews the mean suits.
  if (out_of_core) {
    s.source = std::make_shared<MemoryVolumeSource>(s.volume, s.labels, s.name,
                                                    o.pyramid == "max" ? PyramidKind::Max : PyramidKind::Mean);
  }
  return s;
}

}  // namespace

SourceScene load_source_scene(const SceneOptions& o, bool out_of_core, bool labels_shown) {
  SourceScene s = open_source_scene(o, out_of_core);
  if (s.source && !(s.labelled && labels_shown)) s.source = without_labels(std::move(s.source));
  // The one place sources are opened, so every source kind can be tested under faults.
  if (s.source && !o.inject_faults.empty()) {
    s.source = std::make_shared<FaultInjectingSource>(s.source, parse_fault_spec(o.inject_faults));
  }
  return s;
}

}  // namespace sl::app
