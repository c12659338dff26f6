// `sparseleap info PATH`: what a volume file, OME-Zarr store or Neuroglancer precomputed volume holds.
#include <cstdio>
#include <filesystem>
#include <memory>

#include "apps/commands.h"
#include "apps/scene_loader.h"
#include "cache/formats/nifti/nifti.h"
#include "cache/formats/nrrd/nrrd.h"
#include "cache/stores/store_url.h"
#include "cache/formats/precomputed/source.h"
#include "cache/stores/store_kind.h"
#include "cache/formats/volume_file.h"
#include "cache/formats/zarr/v3_codec.h"
#include "cache/formats/zarr/meta.h"
#include "cache/formats/zarr/source.h"
#include "core/util/error.h"

namespace sl::app {

namespace {

namespace fs = std::filesystem;

struct DiskUsage {
  std::uint64_t bytes = 0;
  std::uint64_t files = 0;
};
DiskUsage disk_usage(const fs::path& dir) {
  DiskUsage u;
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(dir, ec); !ec && it != fs::recursive_directory_iterator();
       it.increment(ec)) {
    if (it->is_regular_file(ec)) {
      u.bytes += it->file_size(ec);
      ++u.files;
    }
  }
  return u;
}

double mib(std::uint64_t b) { return double(b) / (1024.0 * 1024.0); }

// `root`: the store's local directory, or empty for a URL (no file count: listing needs no server
// support the reader relies on).
void print_levels(const zarr::Multiscale& m, const std::string& root) {
  for (std::size_t l = 0; l < m.levels.size(); ++l) {
    const zarr::Level& lv = m.levels[l];
    const ivec3 c = lv.meta.chunk_dims();
    // A sharded v3 array stores one file per shard; its chunks are the inner chunks.
    const zarr::v3::ArrayCodecs* v3 = lv.meta.v3.get();
    const bool sharded = v3 && v3->shard;
    const std::size_t g = sharded ? v3->grid.size() : 0;
    const ivec3 f = sharded ? ivec3(int(v3->grid[g - 1]), int(v3->grid[g - 2]), int(v3->grid[g - 3])) : c;
    const ivec3 n = (lv.dims + f - 1) / f;
    const std::uint64_t total = std::uint64_t(n.x) * std::uint64_t(n.y) * std::uint64_t(n.z);
    std::printf("    %zu  %-5s %5d x %5d x %5d  chunks %dx%dx%d  scale %g %g %g  ", l, ("'" + lv.path + "'").c_str(),
                lv.dims.x, lv.dims.y, lv.dims.z, c.x, c.y, c.z, lv.scale.x, lv.scale.y, lv.scale.z);
    if (root.empty()) {
      std::printf("%llu %s\n", (unsigned long long)total, sharded ? "shards" : "chunks");
      continue;
    }
    const DiskUsage u = disk_usage(fs::path(root) / zarr::join_key(m.prefix, lv.path));
    std::printf("%llu/%llu %s stored\n", (unsigned long long)(u.files > 0 ? u.files - 1 : 0), (unsigned long long)total,
                sharded ? "shards" : "chunks");
  }
}

void print_zarr(const std::string& path, bool stats) {
  const zarr::StoreInfo s = zarr::open_store(path);
  const VolumeDesc& d = s.image.desc;
  const std::string root = is_url(path) ? std::string() : path;
  std::printf("%s (OME-Zarr, Zarr v%d)\n  dims    %d x %d x %d\n  type    %s\n  spacing %g %g %g\n", path.c_str(),
              s.image.levels[0].meta.v3 ? 3 : 2,
              d.dims.x, d.dims.y, d.dims.z, to_string(d.type), d.spacing.x, d.spacing.y, d.spacing.z);
  if (root.empty()) {
    std::printf("  size    %.1f MiB of voxels at level 0 (remote)\n", mib(d.byte_size()));
  } else {
    const DiskUsage u = disk_usage(root);
    std::printf("  size    %.1f MiB of voxels at level 0, %.2f MiB on disk in %llu files\n", mib(d.byte_size()),
                mib(u.bytes), (unsigned long long)u.files);
  }
  std::printf("  compressor %s\n", zarr::describe(s.image.levels[0].meta).c_str());
  std::printf("  levels  %zu\n", s.image.levels.size());
  print_levels(s.image, root);
  if (s.label_names.empty()) {
    std::printf("  labels  none\n");
  } else {
    const zarr::Multiscale& m = *s.labels;
    std::printf("  labels  %zu image(s): ", s.label_names.size());
    for (std::size_t i = 0; i < s.label_names.size(); ++i) std::printf("%s%s", i ? ", " : "", s.label_names[i].c_str());
    std::printf("\n  labels/%s: %s, %zu levels, %s\n", s.label_names[0].c_str(), to_string(m.desc.type), m.levels.size(),
                zarr::describe(m.levels[0].meta).c_str());
    print_levels(m, root);
    // The max label: free when `ingest` recorded it; otherwise a scan of a small level.
    if (stats) std::printf("  max label %u\n", ZarrVolumeSource(path).max_label());
  }
  if (stats) {
    // The range is taken over level 0 read whole: refused, naming its size, before allocating it.
    const zarr::StoreInfo si = zarr::open_store(path);
    check_fits_in_memory(si.image.desc.byte_size(), path, "--stats reads level 0 whole; it",
                         " (its range is not computed out of core)");
    const Volume v = read_zarr_volume(path);
    const vec2 r = value_range(v);
    std::printf("  range   %g .. %g\n", r.x, r.y);
  }
}

// A Neuroglancer precomputed volume: what its `info` says, scale by scale, and what is on disk.
void print_precomputed(const std::string& path, bool stats) {
  // The info alone: no chunk is read unless --stats asks for the data.
  const precomputed::VolumeReader reader(open_byte_store(path), path, std::make_shared<zarr::ChunkCache>(0));
  const precomputed::Info& info = reader.info();
  const VolumeDesc d = info.desc();
  std::printf("%s (Neuroglancer precomputed, %s)\n  dims    %d x %d x %d\n  type    %s (stored %s)\n  spacing %g %g %g\n",
              path.c_str(), info.segmentation ? "segmentation" : "image", d.dims.x, d.dims.y, d.dims.z,
              to_string(d.type), precomputed::to_string(info.data_type), d.spacing.x, d.spacing.y, d.spacing.z);
  if (is_url(path)) {
    std::printf("  size    %.1f MiB of voxels at scale 0 (remote)\n", mib(d.byte_size()));
  } else {
    const DiskUsage u = disk_usage(path);
    std::printf("  size    %.1f MiB of voxels at scale 0, %.2f MiB on disk in %llu files\n", mib(d.byte_size()),
                mib(u.bytes), (unsigned long long)u.files);
  }
  std::printf("  scales  %zu\n", info.scales.size());
  for (std::size_t l = 0; l < info.scales.size(); ++l) {
    const precomputed::Scale& s = info.scales[l];
    std::printf("    %zu  %-12s %5d x %5d x %5d  offset %d %d %d  resolution %g %g %g  chunks %dx%dx%d  %s", l,
                ("'" + s.key + "'").c_str(), s.size.x, s.size.y, s.size.z, s.voxel_offset.x, s.voxel_offset.y,
                s.voxel_offset.z, s.resolution.x, s.resolution.y, s.resolution.z, s.chunk.x, s.chunk.y, s.chunk.z,
                precomputed::to_string(s.encoding));
    if (s.encoding == precomputed::Encoding::CompressedSegmentation) {
      std::printf(" (blocks %dx%dx%d)", s.cseg_block.x, s.cseg_block.y, s.cseg_block.z);
    }
    std::printf("\n");
    if (s.sharding) std::printf("       sharded: %s\n", s.sharding->describe().c_str());
  }
  if (stats) {
    check_fits_in_memory(d.byte_size(), path, "--stats reads scale 0 whole; it", " (its range is not computed out of core)");
    if (info.segmentation) std::printf("  max label %u\n", open_precomputed(path, path)->max_label());
    const vec2 r = value_range(read_precomputed_volume(path));
    std::printf("  range   %g .. %g\n", r.x, r.y);
  }
}

}  // namespace

Runner add_info_command(CLI::App& app) {
  auto path = std::make_shared<std::string>();
  auto full = std::make_shared<bool>(false);
  CLI::App* c = app.add_subcommand("info", "Print dims, type, spacing and value range of a volume or OME-Zarr store");
  c->add_option("path", *path, "Volume file (NRRD, NIfTI-1/-2, TIFF stack), OME-Zarr store (.zarr directory) or Neuroglancer precomputed volume (a directory with `info`, or precomputed://DIR), local or at an http(s):// URL")->required();
  c->add_flag("--stats", *full, "Also read the data and print the value range (and a store's max label)");
  return [path, full] {
    const StoreLocation store = recognise_store(*path);
    if (store.kind == StoreKind::Zarr) {
      print_zarr(store.path, *full);
      return 0;
    }
    if (store.kind == StoreKind::Precomputed) {
      print_precomputed(store.path, *full);
      return 0;
    }
    const VolumeDesc d = read_volume_file_desc(*path);
    std::printf("%s\n  dims    %d x %d x %d\n  type    %s\n  spacing %g %g %g\n  size    %.1f MiB\n",
                path->c_str(), d.dims.x, d.dims.y, d.dims.z, to_string(d.type), d.spacing.x, d.spacing.y,
                d.spacing.z, double(d.byte_size()) / (1024.0 * 1024.0));
    if (is_nifti_path(*path)) {
      const NiftiInfo n = nifti_info(*path);
      std::printf("  format  %s\n  scaling %s\n  orientation %s\n", n.format.c_str(), n.scaling.c_str(),
                  n.orientation.c_str());
    }
    if (*full) {
      const Volume v = read_volume_file(*path);
      const vec2 r = value_range(v);
      std::printf("  range   %g .. %g\n", r.x, r.y);
    }
    return 0;
  };
}

}  // namespace sl::app
