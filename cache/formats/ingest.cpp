#include "cache/formats/ingest.h"

#include <tbb/info.h>
#include <zlib.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <limits>
#include <type_traits>
#include <vector>

#include <unistd.h>

#include "cache/brick.h"
#include "cache/formats/nifti/nifti.h"
#include "cache/formats/nrrd/header.h"
#include "cache/formats/tiff/tiff_stack.h"
#include "cache/formats/zarr/writer.h"
#include "cache/pyramid.h"
#include "core/scene/voxel_dispatch.h"
#include "core/util/error.h"
#include "core/util/parallel.h"

namespace sl {
namespace {

namespace fs = std::filesystem;

void swap_bytes(std::byte* p, std::uint64_t count, int size) {
  for (std::uint64_t i = 0; i < count; ++i, p += size) std::reverse(p, p + size);
}

std::string lower_ext(const std::string& path) {
  std::string s = path;
  for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

bool ends_with(const std::string& s, const std::string& e) {
  return s.size() >= e.size() && s.compare(s.size() - e.size(), e.size(), e) == 0;
}

// NRRD, streamed: the header parsed by nrrd_header.cpp, the data read front to back. gzip data are
// inflated through zlib's gz* stream (byte skip counts decompressed bytes, as teem does).
class NrrdSlabs final : public SlabReader {
 public:
  explicit NrrdSlabs(const std::string& path) : path_(path), h_(nrrd_detail::parse_header(path)) {
    validate_desc(h_.desc, path, std::numeric_limits<std::uint64_t>::max());
    const bool detached = !h_.data_file.empty();
    where_ = detached ? "data file '" + h_.data_file + "': " : "";
    const std::string file = detached ? h_.data_file : path;
    f_ = nrrd_detail::open_read(file, path, where_);
    if (!detached && fseeko(f_.get(), off_t(h_.data_offset), SEEK_SET) != 0) {
      throw InputError(path, "cannot seek: " + nrrd_detail::errno_text());
    }
    for (std::int64_t i = 0; i < h_.line_skip; ++i) {
      int c;
      while ((c = std::getc(f_.get())) != EOF && c != '\n') {
      }
      if (c == EOF) throw InputError(path, where_ + "data truncated: file ends within the skipped lines");
    }
    const std::uint64_t need = h_.desc.byte_size();
    if (h_.gzip) {
      const int fd = ::dup(::fileno(f_.get()));
      if (fd < 0) throw InputError(path, "cannot reopen data");
      if (::lseek(fd, ftello(f_.get()), SEEK_SET) < 0) {
        ::close(fd);
        throw InputError(path, "cannot reopen data");
      }
      gz_.reset(gzdopen(fd, "rb"));
      if (!gz_) {
        ::close(fd);
        throw InputError(path, where_ + "cannot open gzip stream");
      }
      gzbuffer(gz_.get(), 1 << 20);
      std::vector<std::byte> skip(1 << 16);
      for (std::int64_t left = h_.byte_skip; left > 0;) {
        const int n = gzread(gz_.get(), skip.data(), unsigned(std::min<std::int64_t>(left, std::int64_t(skip.size()))));
        if (n <= 0) throw InputError(path, where_ + "gzip data truncated within the skipped bytes");
        left -= n;
      }
      return;
    }
    // Raw: check that all the data are there before reading any (as read_nrrd does).
    std::int64_t pos = ftello(f_.get());
    if (fseeko(f_.get(), 0, SEEK_END) != 0) throw InputError(path, where_ + "cannot seek");
    const std::int64_t size = ftello(f_.get());
    pos = h_.byte_skip == -1 ? std::max<std::int64_t>(pos, size - std::int64_t(need)) : pos + h_.byte_skip;
    const std::uint64_t avail = size > pos ? std::uint64_t(size - pos) : 0;
    if (avail < need) {
      throw InputError(path, where_ + "data truncated: expected " + std::to_string(need) + " bytes of raw data, found " +
                                 std::to_string(avail));
    }
    if (fseeko(f_.get(), pos, SEEK_SET) != 0) throw InputError(path, where_ + "cannot seek");
  }

  const VolumeDesc& desc() const override { return h_.desc; }

  void read(int z0, int nz, std::byte* dst) override {
    SL_CHECK(z0 == next_z_);
    next_z_ = z0 + nz;
    const std::uint64_t n = std::uint64_t(h_.desc.dims.x) * std::uint64_t(h_.desc.dims.y) * std::uint64_t(nz) *
                            std::uint64_t(voxel_size(h_.desc.type));
    for (std::uint64_t done = 0; done < n;) {
      const std::size_t want = std::size_t(std::min<std::uint64_t>(n - done, std::uint64_t(1) << 30));
      if (gz_) {
        const int got = gzread(gz_.get(), dst + done, unsigned(want));
        if (got <= 0) {
          int err = 0;
          const char* msg = gzerror(gz_.get(), &err);
          throw InputError(path_, where_ + (err != Z_OK && err != Z_BUF_ERROR
                                                ? std::string("gzip data are corrupt (") + msg + ")"
                                                : "gzip data truncated at z = " + std::to_string(z0)));
        }
        done += std::uint64_t(got);
      } else {
        const std::size_t got = std::fread(dst + done, 1, want, f_.get());
        if (got == 0) throw InputError(path_, where_ + "read error at z = " + std::to_string(z0));
        done += got;
      }
    }
    const int size = voxel_size(h_.desc.type);
    if (size > 1 && h_.big_endian != (std::endian::native == std::endian::big)) {
      swap_bytes(dst, n / std::uint64_t(size), size);
    }
  }

 private:
  std::string path_, where_;
  nrrd_detail::Header h_;
  nrrd_detail::File f_;
  // Owned through a deleter so that a constructor that throws still closes it.
  struct GzCloser {
    void operator()(gzFile f) const { gzclose(f); }
  };
  std::unique_ptr<std::remove_pointer_t<gzFile>, GzCloser> gz_;
  int next_z_ = 0;
};

// One level's layer buffer in the slab-by-slab pyramid.
struct LayerBuffer {
  ivec3 dims;             // the level's dims
  std::vector<std::byte> data;
  int filled = 0;         // planes held
  int z0 = 0;             // level z of the first held plane
};

class PyramidBuilder {
 public:
  PyramidBuilder(zarr::StoreWriter& w, bool labels, VoxelType t) : w_(w), labels_(labels), type_(t) {
    const int C = w.options().chunk;
    for (int l = 0; l < w.options().levels; ++l) {
      LayerBuffer b;
      b.dims = w.level_dims(l);
      b.data.resize(std::size_t(b.dims.x) * std::size_t(b.dims.y) * std::size_t(C) * std::size_t(voxel_size(t)));
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
    w_.write_slab(labels_, l, b.z0, b.filled, b.data.data());
    if (std::size_t(l) + 1 < levels_.size()) {
      // Each layer starts at an even z (C is even), so it reduces on its own into ceil(filled / 2)
      // planes of the next level.
      LayerBuffer& n = levels_[std::size_t(l) + 1];
      const int out = (b.filled + 1) / 2;
      std::byte* dst = n.data.data() + std::size_t(n.filled) * plane_bytes(l + 1);
      const ivec3 sd(b.dims.x, b.dims.y, b.filled);
      parallel_for(0, out, [&](int lo, int hi) {
        (labels_ ? reduce_mode : reduce_mean)(type_, b.data.data(), sd, dst, lo, hi);
      });
      n.filled += out;
      SL_CHECK(n.filled <= C);
      if (n.filled == C || n.z0 + n.filled == n.dims.z) flush(l + 1, false);
    }
    b.z0 += b.filled;
    b.filled = 0;
  }

  zarr::StoreWriter& w_;
  bool labels_;
  VoxelType type_;
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

}  // namespace

std::unique_ptr<SlabReader> open_nrrd_slabs(const std::string& path) { return std::make_unique<NrrdSlabs>(path); }

std::unique_ptr<SlabReader> open_slab_reader(const std::string& path) {
  const std::string p = lower_ext(path);
  std::error_code ec;
  if (fs::is_directory(path, ec)) return open_tiff_stack(path);
  if (!fs::exists(path, ec)) throw InputError(path, "no such file or directory");
  if (ends_with(p, ".nrrd") || ends_with(p, ".nhdr")) return open_nrrd_slabs(path);
  if (ends_with(p, ".tif") || ends_with(p, ".tiff")) return open_tiff_stack(path);
  if (is_nifti_path(p)) return open_nifti(path);
  throw InputError(path, "unknown input format (expected .nrrd/.nhdr, .tif/.tiff or a directory of them, "
                         ".nii/.nii.gz or .hdr/.img)");
}

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
  std::uint64_t per_voxel_layers = 0;  // voxels in all layer buffers
  ivec3 dims = d.dims;
  for (int l = 0; l < levels; ++l, dims = (dims + 1) / 2) {
    per_voxel_layers += std::uint64_t(dims.x) * std::uint64_t(dims.y) * std::uint64_t(chunk);
  }
  const std::uint64_t chunk_voxels = std::uint64_t(chunk) * std::uint64_t(chunk) * std::uint64_t(chunk);
  const std::uint64_t threads = std::uint64_t(std::max(1, tbb::info::default_concurrency()));
  // A sharded level holds up to `shard` chunk layers of encoded chunks until its shard layer is complete.
  per_voxel_layers *= std::uint64_t(1 + shard);
  std::uint64_t b = per_voxel_layers * std::uint64_t(voxel_size(d.type)) +
                    2 * threads * chunk_voxels * std::uint64_t(voxel_size(d.type));  // chunk + encoded copy
  if (label_type) {
    b += per_voxel_layers * std::uint64_t(voxel_size(*label_type)) +
         2 * threads * chunk_voxels * std::uint64_t(voxel_size(*label_type));
  }
  return b;
}

IngestResult ingest(const std::string& in, const std::string& out, const IngestOptions& o) {
  if (o.chunk < 8 || o.chunk > 512 || o.chunk % 2 != 0) {
    throw InputError("--chunk", "must be an even number between 8 and 512, got " + std::to_string(o.chunk));
  }
  if (o.zarr_format != 2 && o.zarr_format != 3) throw InputError("--format", "must be zarr2 or zarr3");
  if (o.shard != 0 && o.zarr_format != 3) throw InputError("--shard", "needs --format zarr3 (Zarr v2 has no shards)");
  if (o.shard < 0 || o.shard > 64) throw InputError("--shard", "must be 1-64 chunks, got " + std::to_string(o.shard));
  if (o.zarr_format == 3 && o.compressor.id == zarr::Compressor::Id::Zlib) {
    throw InputError("--compressor", "zlib has no Zarr v3 codec (use gzip)");
  }
  std::unique_ptr<SlabReader> image = open_slab_reader(in);
  std::unique_ptr<SlabReader> labels;
  if (!o.labels.empty()) {
    labels = open_slab_reader(o.labels);
    if (labels->desc().dims != image->desc().dims) {
      throw InputError(o.labels, "label volume dims differ from the intensity volume's");
    }
    if (labels->desc().type == VoxelType::F32) throw InputError(o.labels, "label volume must be of an integer type");
  }
  const VolumeDesc desc = image->desc();

  fs::path dst(out);
  while (dst.has_filename() == false && dst.has_parent_path() && dst != dst.root_path()) dst = dst.parent_path();
  std::error_code ec;
  if (fs::exists(dst, ec) && !o.force) throw InputError(out, "exists; pass --force to replace it");
  // --force replaces a store, which is a folder: a file, a device or a FIFO there is not one (renaming
  // over /dev/full would destroy the device).
  if (const auto t = fs::symlink_status(dst, ec).type(); t != fs::file_type::not_found && t != fs::file_type::directory) {
    throw InputError(out, "exists and is not a folder (a store is one); not replaced");
  }
  const fs::path parent = dst.has_parent_path() ? dst.parent_path() : fs::path(".");
  if (!fs::is_directory(parent, ec)) throw InputError(out, "directory '" + parent.string() + "' does not exist");
  // Hidden and suffixed: a store being written never looks like a finished one.
  // (Built with append: GCC 12 warns falsely, -Wrestrict, on `"." + std::string`.)
  const auto hidden = [&](const char* tag) {
    std::string name(1, '.');
    name.append(dst.filename().string()).append(tag).append(std::to_string(::getpid()));
    return parent / name;
  };
  const fs::path tmp = hidden(".part-");
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
    if (labels) wo.label_type = labels->desc().type;
    zarr::StoreWriter w(tmp, out, desc, wo);
    PyramidBuilder pi(w, false, desc.type);
    std::optional<PyramidBuilder> pl;
    if (labels) pl.emplace(w, true, labels->desc().type);
    const std::uint64_t plane = std::uint64_t(desc.dims.x) * std::uint64_t(desc.dims.y);
    const std::uint64_t total = desc.byte_size() + (labels ? labels->desc().byte_size() : 0);
    for (int z0 = 0; z0 < desc.dims.z; z0 += o.chunk) {
      const int nz = std::min(o.chunk, desc.dims.z - z0);
      image->read(z0, nz, pi.level0());
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
    pi.finish();
    if (pl) {
      pl->finish();
      w.set_max_label(r.max_label);
    }
    r.stored_bytes = w.bytes_written();
    // Publish: the complete store appears under its name in one rename (a replaced store is moved
    // aside first and removed only after the new one is in place).
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
  } catch (...) {
    fs::remove_all(tmp, ec);
    throw;
  }
  return r;
}

}  // namespace sl
