#include "cache/formats/ingest.h"

#include <tbb/info.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <vector>

#include "cache/brick.h"
#include "cache/formats/volume_file.h"
#include "cache/formats/zarr/writer.h"
#include "cache/pyramid.h"
#include "core/scene/voxel_dispatch.h"
#include "core/util/error.h"
#include "core/util/parallel.h"

namespace sl {
namespace {

namespace fs = std::filesystem;

// One level's layer buffer in the slab-by-slab pyramid.
struct LayerBuffer {
  ivec3 dims;             // the level's dims
  std::vector<std::byte> data;
  int filled = 0;         // planes held
  int z0 = 0;             // level z of the first held plane
};

// One pyramid of the store, level by level. The max pyramid starts at level 1: it is fed the image's
// level-0 layers (`max_from_level0`) and keeps no level-0 buffer of its own.
class PyramidBuilder {
 public:
  PyramidBuilder(zarr::StoreWriter& w, zarr::Target target, VoxelType t, PyramidBuilder* max = nullptr)
      : w_(w), target_(target), type_(t), max_(max) {
    const int C = w.options().chunk;
    for (int l = 0; l < w.options().levels; ++l) {
      LayerBuffer b;
      b.dims = w.level_dims(l);
      if (l > 0 || target != zarr::Target::Max) {
        b.data.resize(std::size_t(b.dims.x) * std::size_t(b.dims.y) * std::size_t(C) * std::size_t(voxel_size(t)));
      }
      levels_.push_back(std::move(b));
    }
  }
  // Level 0's buffer, to read the next layer into.
  std::byte* level0() { return levels_[0].data.data(); }
  // Level 0 received `nz` planes: write, reduce and cascade.
  void push_level0(int nz) {
    levels_[0].filled = nz;
    flush(0, false);
  }
  // End of input: flush the partial layers, finest first.
  void finish() {
    for (std::size_t l = 0; l < levels_.size(); ++l) {
      if (levels_[l].filled > 0) flush(int(l), true);
    }
  }

 private:
  std::size_t plane_bytes(int l) const {
    const ivec3 d = levels_[std::size_t(l)].dims;
    return std::size_t(d.x) * std::size_t(d.y) * std::size_t(voxel_size(type_));
  }
  void flush(int l, bool final) {
    const int C = w_.options().chunk;
    LayerBuffer& b = levels_[std::size_t(l)];
    if (b.filled < C && !final && b.z0 + b.filled < b.dims.z) return;
    w_.write_slab(target_, l, b.z0, b.filled, b.data.data());
    if (l == 0 && max_) max_->reduce_into(1, b);
    if (std::size_t(l) + 1 < levels_.size()) reduce_into(l + 1, b);
    b.z0 += b.filled;
    b.filled = 0;
  }
  // Reduces the layer `b` of level l - 1 (of this pyramid, or the image's level 0 for the max one)
  // into level l. Each layer starts at an even z (C is even), so it reduces on its own into
  // ceil(filled / 2) planes of the next level.
  void reduce_into(int l, const LayerBuffer& b) {
    const int C = w_.options().chunk;
    const ReduceFn reduce = target_ == zarr::Target::Labels ? reduce_mode
                                                            : intensity_reduction(target_ == zarr::Target::Max
                                                                                      ? PyramidKind::Max
                                                                                      : PyramidKind::Mean);
    LayerBuffer& n = levels_[std::size_t(l)];
    const int out = (b.filled + 1) / 2;
    std::byte* dst = n.data.data() + std::size_t(n.filled) * plane_bytes(l);
    const ivec3 sd(b.dims.x, b.dims.y, b.filled);
    parallel_for(0, out, [&](int lo, int hi) { reduce(type_, b.data.data(), sd, dst, lo, hi); });
    n.filled += out;
    SL_CHECK(n.filled <= C);
    if (n.filled == C || n.z0 + n.filled == n.dims.z) flush(l, false);
  }

  zarr::StoreWriter& w_;
  zarr::Target target_;
  VoxelType type_;
  PyramidBuilder* max_;  // fed this pyramid's level-0 layers
  std::vector<LayerBuffer> levels_;
};

std::uint32_t slab_max_label(VoxelType t, const std::byte* p, std::size_t n) {
  return dispatch_label(
      t,
      [&](auto tag) {
        const auto* v = reinterpret_cast<const decltype(tag)*>(p);
        std::uint32_t m = 0;
        for (std::size_t i = 0; i < n; ++i) m = std::max<std::uint32_t>(m, v[i]);
        return m;
      },
      [] { return std::uint32_t(0); });  // refused earlier (integer labels only)
}

void check_options(const IngestOptions& o) {
  if (o.chunk < 8 || o.chunk > 512 || o.chunk % 2 != 0) {
    throw InputError("--chunk", "must be an even number between 8 and 512, got " + std::to_string(o.chunk));
  }
  if (o.zarr_format != 2 && o.zarr_format != 3) throw InputError("--format", "must be zarr2 or zarr3");
  if (o.shard != 0 && o.zarr_format != 3) throw InputError("--shard", "needs --format zarr3 (Zarr v2 has no shards)");
  if (o.shard < 0 || o.shard > 64) throw InputError("--shard", "must be 1-64 chunks, got " + std::to_string(o.shard));
  if (o.zarr_format == 3 && o.compressor.id == zarr::Compressor::Id::Zlib) {
    throw InputError("--compressor", "zlib has no Zarr v3 codec (use gzip)");
  }
}

// The label volume of o.labels, checked against the image; null without one.
std::unique_ptr<SlabReader> open_labels(const IngestOptions& o, const SlabReader& image) {
  if (o.labels.empty()) return nullptr;
  std::unique_ptr<SlabReader> labels = open_slab_reader(o.labels);
  if (labels->desc().dims != image.desc().dims) {
    throw InputError(o.labels, "label volume dims differ from the intensity volume's");
  }
  if (labels->desc().type == VoxelType::F32) throw InputError(o.labels, "label volume must be of an integer type");
  return labels;
}

// Where the store goes: `dst` (OUT without trailing separators) in `parent`, written first under a
// hidden name beside it.
struct Destination {
  fs::path dst, parent;

  Destination(const std::string& out, bool force) : dst(out) {
    while (dst.has_filename() == false && dst.has_parent_path() && dst != dst.root_path()) dst = dst.parent_path();
    std::error_code ec;
    if (fs::exists(dst, ec) && !force) throw InputError(out, "exists; pass --force to replace it");
    // --force replaces a store, which is a folder: a file, a device or a FIFO there is not one (renaming
    // over /dev/full would destroy the device).
    if (const auto t = fs::symlink_status(dst, ec).type(); t != fs::file_type::not_found && t != fs::file_type::directory) {
      throw InputError(out, "exists and is not a folder (a store is one); not replaced");
    }
    parent = dst.has_parent_path() ? dst.parent_path() : fs::path(".");
    if (!fs::is_directory(parent, ec)) throw InputError(out, "directory '" + parent.string() + "' does not exist");
  }

  // Hidden and suffixed: a store being written never looks like a finished one.
  // (Built with append: GCC 12 warns falsely, -Wrestrict, on `"." + std::string`.)
  fs::path hidden(const char* tag) const {
    std::string name(1, '.');
    name.append(dst.filename().string()).append(tag).append(std::to_string(::getpid()));
    return parent / name;
  }

  // The complete store appears under its name in one rename (a replaced store is moved aside first and
  // removed only after the new one is in place).
  void publish(const fs::path& tmp, const std::string& out) const {
    std::error_code ec;
    fs::path old;
    if (fs::exists(dst, ec)) {
      old = hidden(".old-");
      fs::rename(dst, old, ec);
      if (ec) throw InputError(out, "cannot replace the existing store: " + ec.message());
    }
    fs::rename(tmp, dst, ec);
    if (ec) {
      if (!old.empty()) fs::rename(old, dst, ec);
      throw InputError(out, "cannot rename the finished store into place: " + ec.message());
    }
    if (!old.empty()) fs::remove_all(old, ec);
  }
};

// Reads the inputs slab by slab into the store's pyramids; fills r's byte counts and largest label.
void write_store(zarr::StoreWriter& w, SlabReader& image, SlabReader* labels, const IngestOptions& o, IngestResult& r) {
  const VolumeDesc& desc = r.desc;
  std::optional<PyramidBuilder> pm;
  if (w.has_max_levels()) pm.emplace(w, zarr::Target::Max, desc.type);
  PyramidBuilder pi(w, zarr::Target::Image, desc.type, pm ? &*pm : nullptr);
  std::optional<PyramidBuilder> pl;
  if (labels) pl.emplace(w, zarr::Target::Labels, labels->desc().type);
  const std::uint64_t plane = std::uint64_t(desc.dims.x) * std::uint64_t(desc.dims.y);
  const std::uint64_t total = desc.byte_size() + (labels ? labels->desc().byte_size() : 0);
  for (int z0 = 0; z0 < desc.dims.z; z0 += o.chunk) {
    const int nz = std::min(o.chunk, desc.dims.z - z0);
    image.read(z0, nz, pi.level0());
    r.input_bytes += plane * std::uint64_t(nz) * std::uint64_t(voxel_size(desc.type));
    pi.push_level0(nz);
    if (labels) {
      labels->read(z0, nz, pl->level0());
      const VoxelType lt = labels->desc().type;
      r.max_label = std::max(r.max_label, slab_max_label(lt, pl->level0(), std::size_t(plane) * std::size_t(nz)));
      r.input_bytes += plane * std::uint64_t(nz) * std::uint64_t(voxel_size(lt));
      pl->push_level0(nz);
    }
    if (o.progress) o.progress(r.input_bytes, total);
  }
  pi.finish();  // its level 0's last layer feeds the max pyramid first
  if (pm) pm->finish();
  if (pl) {
    pl->finish();
    w.set_max_label(r.max_label);
  }
  r.stored_bytes = w.bytes_written();
}

}  // namespace

int ingest_levels(ivec3 dims, int chunk) {
  int levels = 1;
  while ((dims.x > chunk || dims.y > chunk || dims.z > chunk) && levels < kMaxBrickLevels) {
    dims = (dims + 1) / 2;
    ++levels;
  }
  return levels;
}

std::uint64_t memory_bound(const VolumeDesc& d, std::optional<VoxelType> label_type, int chunk, int shard) {
  const int levels = ingest_levels(d.dims, chunk);
  std::uint64_t per_voxel_layers = 0;  // voxels in all layer buffers of one pyramid
  std::uint64_t max_layers = 0;        // the max pyramid's: levels >= 1
  ivec3 dims = d.dims;
  for (int l = 0; l < levels; ++l, dims = (dims + 1) / 2) {
    per_voxel_layers += std::uint64_t(dims.x) * std::uint64_t(dims.y) * std::uint64_t(chunk);
    if (l > 0) max_layers += std::uint64_t(dims.x) * std::uint64_t(dims.y) * std::uint64_t(chunk);
  }
  const std::uint64_t chunk_voxels = std::uint64_t(chunk) * std::uint64_t(chunk) * std::uint64_t(chunk);
  const std::uint64_t threads = std::uint64_t(std::max(1, tbb::info::default_concurrency()));
  // A sharded level holds up to `shard` chunk layers of encoded chunks until its shard layer is complete.
  per_voxel_layers *= std::uint64_t(1 + shard);
  max_layers *= std::uint64_t(1 + shard);
  std::uint64_t b = (per_voxel_layers + max_layers) * std::uint64_t(voxel_size(d.type)) +
                    2 * threads * chunk_voxels * std::uint64_t(voxel_size(d.type));  // chunk + encoded copy
  if (label_type) {
    b += per_voxel_layers * std::uint64_t(voxel_size(*label_type)) +
         2 * threads * chunk_voxels * std::uint64_t(voxel_size(*label_type));
  }
  return b;
}

IngestResult ingest(const std::string& in, const std::string& out, const IngestOptions& o) {
  check_options(o);
  std::unique_ptr<SlabReader> image = open_slab_reader(in);
  std::unique_ptr<SlabReader> labels = open_labels(o, *image);
  const VolumeDesc desc = image->desc();
  const Destination d(out, o.force);
  std::error_code ec;
  const fs::path tmp = d.hidden(".part-");
  fs::remove_all(tmp, ec);

  IngestResult r;
  r.desc = desc;
  r.levels = ingest_levels(desc.dims, o.chunk);
  r.memory_bound = memory_bound(desc, labels ? std::optional(labels->desc().type) : std::nullopt, o.chunk, o.shard);
  if (o.max_memory && r.memory_bound > o.max_memory) {
    const auto mib = [](std::uint64_t b) { return std::to_string((b + (1u << 20) - 1) >> 20) + " MiB"; };
    throw InputError(in, "ingest would need " + mib(r.memory_bound) + " for its layers of chunk x X x Y voxels, more than " +
                             mib(o.max_memory) + " (half of this machine's memory); choose a smaller --chunk" +
                             (o.shard ? std::string(" or --shard") : std::string()));
  }
  try {
    zarr::WriterOptions wo;
    wo.chunk = o.chunk;
    wo.compressor = o.compressor;
    wo.levels = r.levels;
    wo.zarr_format = o.zarr_format;
    wo.shard = o.shard;
    wo.max_levels = true;
    if (labels) wo.label_type = labels->desc().type;
    zarr::StoreWriter w(tmp, out, desc, wo);
    write_store(w, *image, labels.get(), o, r);
    d.publish(tmp, out);
  } catch (...) {
    fs::remove_all(tmp, ec);
    throw;
  }
  return r;
}

}  // namespace sl
