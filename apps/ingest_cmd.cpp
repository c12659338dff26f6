// `sparseleap ingest IN OUT.zarr`: NRRD, TIFF stack or NIfTI to an OME-Zarr store with a full pyramid
// (cache/ingest.h), with a progress bar on a terminal and periodic plain lines otherwise.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <stdexcept>

#include <unistd.h>

#include "apps/commands.h"
#include "apps/scene_loader.h"
#include "cache/formats/ingest.h"
#include "core/util/error.h"

namespace sl::app {

namespace {

struct IngestCmdOptions {
  std::string in, out, labels;
  int chunk = 64;
  std::string compressor = "blosc-zstd";
  std::string format = "zarr2";
  int shard = 0;
  std::optional<int> level;  // the codec's default when not given
  bool force = false;
};

std::string clock_text(double s) {
  if (!(s >= 0.0) || s > 1e7) return "--:--";
  const long t = long(s + 0.5);
  char buf[32];
  if (t >= 3600) {
    std::snprintf(buf, sizeof buf, "%ld:%02ld:%02ld", t / 3600, (t / 60) % 60, t % 60);
  } else {
    std::snprintf(buf, sizeof buf, "%ld:%02ld", t / 60, t % 60);
  }
  return buf;
}

// On a terminal: one line redrawn with \r (at most 5 times a second): bar, %, MB/s, ETA. Otherwise a
// plain line every 5 s or every 10 %, whichever comes first (none in the first second), so logs stay
// short but alive.
class Progress {
 public:
  Progress() : tty_(::isatty(2)), start_(Clock::now()), last_(start_) {}
  void update(std::uint64_t done, std::uint64_t total) {
    const auto now = Clock::now();
    const double t = std::chrono::duration<double>(now - start_).count();
    const double since = std::chrono::duration<double>(now - last_).count();
    const double frac = total ? double(done) / double(total) : 1.0;
    const double mbs = t > 0.0 ? double(done) / 1e6 / t : 0.0;
    const double eta = done > 0 ? t * (double(total) - double(done)) / double(done) : -1.0;
    if (tty_) {
      if (since < 0.2 && done < total) return;
      char bar[31];
      const int fill = int(frac * 30.0);
      for (int i = 0; i < 30; ++i) bar[i] = i < fill ? '#' : '.';
      bar[30] = 0;
      std::fprintf(stderr, "\r  ingest [%s] %3d%%  %7.1f MB/s  ETA %s   ", bar, int(frac * 100.0), mbs,
                   clock_text(eta).c_str());
      drawn_ = true;
    } else {
      // Nothing in the first second: a quick run (or an early error) stays free of progress noise.
      const int decile = int(frac * 10.0);
      if (t < 1.0 || (since < 5.0 && decile <= decile_)) return;
      decile_ = decile;
      std::fprintf(stderr, "ingest: %3d%% (%.0f of %.0f MB), %.1f MB/s, ETA %s\n", int(frac * 100.0),
                   double(done) / 1e6, double(total) / 1e6, mbs, clock_text(eta).c_str());
    }
    last_ = now;
  }
  void clear() {
    if (tty_ && drawn_) std::fprintf(stderr, "\r%78s\r", "");
  }
  double seconds() const { return std::chrono::duration<double>(Clock::now() - start_).count(); }

 private:
  using Clock = std::chrono::steady_clock;
  bool tty_;
  Clock::time_point start_, last_;
  int decile_ = 0;
  bool drawn_ = false;
};

// True when `a` and `b` are the same path or one lies inside the other (after resolving symlinks and
// `..`): writing OUT there, with --force removing what was there first, would destroy the input.
bool paths_overlap(const std::string& a, const std::string& b) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path pa = fs::weakly_canonical(fs::absolute(a, ec), ec);
  const fs::path pb = fs::weakly_canonical(fs::absolute(b, ec), ec);
  const auto prefix = [](const fs::path& outer, const fs::path& inner) {
    auto o = outer.begin(), i = inner.begin();
    for (; o != outer.end() && !o->empty(); ++o, ++i) {
      if (i == inner.end() || *o != *i) return false;
    }
    return true;
  };
  return prefix(pa, pb) || prefix(pb, pa);
}

int run_ingest(const IngestCmdOptions& o) {
  // An empty name would resolve to the current folder (and hold the input): refused, not tried.
  if (o.in.empty()) throw InputError("IN", "the input name is empty");
  if (o.out.empty()) throw InputError("OUT", "the output name is empty");
  for (const std::string& in : {o.in, o.labels}) {
    if (!in.empty() && paths_overlap(in, o.out)) {
      throw InputError(o.out, "is the input " + in + " (or holds it, or lies inside it); choose another OUT");
    }
  }
  IngestOptions io;
  io.chunk = o.chunk;
  try {
    io.compressor = zarr::compressor_from_name(o.compressor, o.level);
  } catch (const std::runtime_error& e) {
    // The codec's message starts with "level" when it is the level that is refused.
    const std::string what = e.what();
    if (what.rfind("level: ", 0) == 0) throw InputError("--level", what.substr(7));
    throw InputError(what.rfind("level", 0) == 0 ? "--level" : "--compressor", what);
  }
  if (o.format != "zarr2" && o.format != "zarr3") throw InputError("--format", "must be zarr2 or zarr3, got '" + o.format + "'");
  io.zarr_format = o.format == "zarr3" ? 3 : 2;
  io.shard = o.shard;
  io.labels = o.labels;
  io.force = o.force;
  io.max_memory = in_memory_limit();
  auto progress = std::make_shared<Progress>();
  io.progress = [progress](std::uint64_t done, std::uint64_t total) { progress->update(done, total); };
  IngestResult r;
  try {
    r = ingest(o.in, o.out, io);
  } catch (...) {
    progress->clear();
    throw;
  }
  progress->clear();
  const double s = progress->seconds();
  const VolumeDesc& d = r.desc;
  std::printf("wrote %s: %dx%dx%d %s%s, %d levels, chunk %d, %s\n", o.out.c_str(), d.dims.x, d.dims.y, d.dims.z,
              to_string(d.type), o.labels.empty() ? "" : " + labels", r.levels, o.chunk, zarr::describe(io.compressor).c_str());
  std::printf("  %.1f MB in %.1f s (%.1f MB/s), %.1f MB stored with the pyramid (input/stored %.2f), memory bound %.0f MiB\n",
              double(r.input_bytes) / 1e6, s, s > 0 ? double(r.input_bytes) / 1e6 / s : 0.0, double(r.stored_bytes) / 1e6,
              r.stored_bytes ? double(r.input_bytes) / double(r.stored_bytes) : 0.0, double(r.memory_bound) / 1048576.0);
  return 0;
}

}  // namespace

Runner add_ingest_command(CLI::App& app) {
  auto o = std::make_shared<IngestCmdOptions>();
  CLI::App* c = app.add_subcommand(
      "ingest",
      "Convert NRRD, a TIFF stack or NIfTI into an OME-Zarr store (NGFF 0.4 on Zarr v2, or with --format zarr3 NGFF 0.5 on Zarr v3) with a full pyramid. "
      "Built slab by slab: peak memory is about 4/3 x chunk x X x Y x bytes-per-voxel (plus the same for "
      "labels), independent of the depth Z.");
  c->add_option("in", o->in, "Input: .nrrd/.nhdr, .tif/.tiff (multipage) or a directory of 2-D TIFFs, .nii/.nii.gz")
      ->required();
  c->add_option("out", o->out, "Output store (directory, e.g. volume.zarr)")->required();
  c->add_option("--chunk", o->chunk, "Chunk edge in voxels (even, 8-512)")->capture_default_str();
  c->add_option("--compressor", o->compressor, "none, zlib, gzip, zstd, blosc-lz4, blosc-zstd or blosc-zlib")
      ->capture_default_str();
  c->add_option("--format", o->format, "zarr2 (NGFF 0.4 on Zarr v2) or zarr3 (NGFF 0.5 on Zarr v3)")->capture_default_str();
  c->add_option("--shard", o->shard, "Zarr v3: shards of N x N x N chunks (sharding_indexed; 0: no shards)")
      ->capture_default_str();
  c->add_option("--level", o->level,
                "Compression level (default: zlib/gzip 6, zstd 3, blosc 5; ranges zlib/gzip/blosc 0-9, zstd 0-22; a level "
                "outside the range is refused)");
  c->add_option("--labels", o->labels, "Label volume to store as the NGFF label image labels/labels (integer type)");
  c->add_flag("--force", o->force, "Replace OUT if it exists");
  return [o] { return run_ingest(*o); };
}

}  // namespace sl::app
