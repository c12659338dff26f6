#include "cache/formats/zarr/writer.h"

#include <bit>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>
#include <nlohmann/json.hpp>

#include "cache/formats/zarr/v2_array.h"
#include "cache/formats/zarr/v3_writer.h"
#include "core/util/error.h"
#include "core/util/parallel.h"

namespace sl::zarr {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

// Zarr stores are written little-endian ("<u2"); the slab data are copied as they are.
static_assert(std::endian::native == std::endian::little, "the Zarr writer assumes a little-endian host");

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};

bool all_zero(const std::byte* p, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) {
    if (p[i] != std::byte{0}) return false;
  }
  return true;
}

}  // namespace

StoreWriter::StoreWriter(const fs::path& dir, std::string who, const VolumeDesc& desc, const WriterOptions& o)
    : dir_(dir), who_(std::move(who)), desc_(desc), o_(o) {
  SL_CHECK(o_.levels >= 1 && o_.chunk >= 1);
  std::error_code ec;
  if (!fs::create_directory(dir_, ec) || ec) {
    throw InputError(who_, "cannot create '" + dir_.string() + "': " + (ec ? ec.message() : "it exists"));
  }
  SL_CHECK(o_.zarr_format == 2 || o_.zarr_format == 3);
  SL_CHECK(o_.shard == 0 || o_.zarr_format == 3);
  write_group(dir_, "image", Target::Image);
  if (has_max_levels()) {
    fs::create_directory(dir_ / "max", ec);
    if (ec) throw InputError(who_, "cannot create '" + (dir_ / "max").string() + "': " + ec.message());
    write_group(dir_ / "max", "max", Target::Max);
  }
  if (o_.label_type) {
    fs::create_directory(dir_ / "labels", ec);
    if (o_.zarr_format == 3) {
      write_json(dir_ / "labels" / "zarr.json",
                 json{{"zarr_format", 3}, {"node_type", "group"},
                      {"attributes", {{"ome", {{"version", "0.5"}, {"labels", {"labels"}}}}}}}.dump(2));
    } else {
      write_json(dir_ / "labels" / ".zgroup", "{\n  \"zarr_format\": 2\n}");
      write_json(dir_ / "labels" / ".zattrs", json{{"labels", {"labels"}}}.dump(2));
    }
    fs::create_directory(dir_ / "labels" / "labels", ec);
    if (ec) throw InputError(who_, "cannot create '" + (dir_ / "labels").string() + "': " + ec.message());
    write_group(dir_ / "labels" / "labels", "labels", Target::Labels);
  }
}

ivec3 StoreWriter::level_dims(int level) const {
  ivec3 d = desc_.dims;
  for (int l = 0; l < level; ++l) d = (d + 1) / 2;
  return d;
}

void StoreWriter::write_file(const fs::path& p, const void* data, std::size_t n) const {
  std::unique_ptr<std::FILE, FileCloser> f(std::fopen(p.c_str(), "wb"));
  if (!f || (n && std::fwrite(data, 1, n, f.get()) != n) || std::fclose(f.release()) != 0) {
    throw InputError(who_, "writing '" + p.string() + "' failed: " + std::strerror(errno));
  }
  bytes_written_ += n;
}

void StoreWriter::write_json(const fs::path& p, const std::string& text) const {
  const std::string t = text + "\n";
  write_file(p, t.data(), t.size());
}

fs::path StoreWriter::attrs_file(const fs::path& group) const {
  return group / (o_.zarr_format == 3 ? "zarr.json" : ".zattrs");
}

fs::path StoreWriter::array_dir(Target target, int level) const {
  const fs::path group = target == Target::Labels ? dir_ / "labels" / "labels" : target == Target::Max ? dir_ / "max" : dir_;
  return group / std::to_string(level);
}

// One multiscale group: .zgroup, .zattrs (NGFF 0.4 multiscales: axes z, y, x in the spacing's unit-
// less space, per-level scale = spacing * 2^l) and each level's .zarray. The max group lists levels
// 1, 2, ... under their level numbers, so it is a multiscale image of its own (at half resolution)
// that generic readers can open; the image's attributes name it for sparseleap.
void StoreWriter::write_group(const fs::path& group, const std::string& name, Target target) const {
  const bool v3 = o_.zarr_format == 3;
  const bool labels = target == Target::Labels;
  const int first = target == Target::Max ? 1 : 0;
  json datasets = json::array();
  for (int l = first; l < o_.levels; ++l) {
    const float f = float(1 << l);
    const json scale = {double(desc_.spacing.z * f), double(desc_.spacing.y * f), double(desc_.spacing.x * f)};
    datasets.push_back({{"path", std::to_string(l)},
                        {"coordinateTransformations", json::array({{{"type", "scale"}, {"scale", scale}}})}});
  }
  json ms = {{"name", name},
             {"axes", json::array({{{"name", "z"}, {"type", "space"}},
                                   {{"name", "y"}, {"type", "space"}},
                                   {{"name", "x"}, {"type", "space"}}})},
             {"datasets", datasets},
             {"type", labels ? "mode" : target == Target::Max ? "max" : "mean"},
             {"metadata", {{"method", "sparseleap 2x reduction (DESIGN.md section 3)"}}}};
  // NGFF 0.4 versions each multiscale; 0.5 versions the "ome" object that holds them (zarr.json).
  if (!v3) ms["version"] = "0.4";
  json attrs = {{"multiscales", json::array({ms})}};
  if (labels) attrs["image-label"] = {{"version", v3 ? "0.5" : "0.4"}, {"source", {{"image", "../../"}}}};
  // Outside the NGFF attributes (NGFF 0.5 reserves "ome"), as the label image's max_label.
  const json ours = target == Target::Image && has_max_levels() ? json{{"max_pyramid", "max"}} : json();
  if (v3) {
    attrs["version"] = "0.5";
    json node = {{"zarr_format", 3}, {"node_type", "group"}, {"attributes", {{"ome", attrs}}}};
    if (!ours.is_null()) node["attributes"]["sparseleap"] = ours;
    write_json(group / "zarr.json", node.dump(2));
  } else {
    if (!ours.is_null()) attrs["sparseleap"] = ours;
    write_json(group / ".zgroup", "{\n  \"zarr_format\": 2\n}");
    write_json(group / ".zattrs", attrs.dump(2));
  }
  for (int l = first; l < o_.levels; ++l) {
    ArrayMeta m;
    const ivec3 d = level_dims(l);
    m.shape = {d.z, d.y, d.x};
    m.chunks = {o_.chunk, o_.chunk, o_.chunk};
    m.type = labels ? *o_.label_type : desc_.type;
    m.fill = 0.0;
    m.separator = '/';  // NGFF 0.4 requires "/"
    m.compressor = o_.compressor;
    std::error_code ec;
    fs::create_directory(group / std::to_string(l), ec);
    if (ec) throw InputError(who_, "cannot create '" + (group / std::to_string(l)).string() + "': " + ec.message());
    if (v3) {
      json a;
      try {
        a = v3::array_json(d, o_.chunk, o_.shard, m.type, o_.compressor);
      } catch (const std::runtime_error& e) {
        throw InputError(who_, e.what());
      }
      write_json(group / std::to_string(l) / "zarr.json", a.dump(2));
    } else {
      write_json(group / std::to_string(l) / ".zarray", v2::to_json(m).dump(2));
    }
  }
}

void StoreWriter::set_max_label(std::uint32_t max_label) {
  SL_CHECK(o_.label_type.has_value());
  const fs::path p = attrs_file(dir_ / "labels" / "labels");
  std::FILE* f = std::fopen(p.c_str(), "rb");
  std::string text;
  if (f) {
    char buf[4096];
    for (std::size_t n; (n = std::fread(buf, 1, sizeof buf, f)) > 0;) text.append(buf, n);
    std::fclose(f);
  }
  json attrs = json::parse(text);
  (o_.zarr_format == 3 ? attrs["attributes"] : attrs)["sparseleap"] = {{"max_label", max_label}};
  write_json(p, attrs.dump(2));
}

void StoreWriter::write_slab(Target target, int level, int z0, int nz, const std::byte* data) {
  const bool labels = target == Target::Labels;
  SL_CHECK(level >= 0 && level < o_.levels && (!labels || o_.label_type));
  SL_CHECK(target != Target::Max || (level >= 1 && has_max_levels()));
  const ivec3 d = level_dims(level);
  const int C = o_.chunk;
  SL_CHECK(z0 % C == 0 && nz >= 1 && z0 + nz <= d.z && (nz == C || z0 + nz == d.z));
  const VoxelType t = labels ? *o_.label_type : desc_.type;
  const std::size_t elem = std::size_t(voxel_size(t));
  const fs::path arr = array_dir(target, level);
  const int cz = z0 / C;
  const int ncx = (d.x + C - 1) / C, ncy = (d.y + C - 1) / C;
  // Chunk (or shard) files: v2 "z/y/x", v3 "c/z/y/x".
  const int S = std::max(o_.shard, 1);
  const fs::path files = o_.zarr_format == 3 ? arr / "c" : arr;
  const int nfx = (ncx + S - 1) / S, nfy = (ncy + S - 1) / S, fz = cz / S;
  std::error_code ec;
  if (cz % S == 0) {
    for (int fy = 0; fy < nfy; ++fy) {
      fs::create_directories(files / std::to_string(fz) / std::to_string(fy), ec);
      if (ec) throw InputError(who_, "cannot create '" + files.string() + "/...': " + ec.message());
    }
  }
  std::vector<std::vector<std::optional<std::vector<std::byte>>>>* shards = nullptr;
  if (o_.shard > 0) {
    shards = &pending_[{target, level}];
    if (cz % S == 0) shards->assign(std::size_t(nfx) * std::size_t(nfy), std::vector<std::optional<std::vector<std::byte>>>(std::size_t(S) * S * S));
  }
  parallel_for(0, ncx * ncy, [&](int i) {
    const int cx = i % ncx, cy = i / ncx;
    // Edge chunks are stored full size, padded with the fill value (Zarr v2).
    std::vector<std::byte> chunk(std::size_t(C) * std::size_t(C) * std::size_t(C) * elem, std::byte{0});
    const int x0 = cx * C, y0 = cy * C;
    const int nx = std::min(C, d.x - x0), ny = std::min(C, d.y - y0);
    for (int z = 0; z < nz; ++z) {
      for (int y = 0; y < ny; ++y) {
        const std::byte* src =
            data + ((std::size_t(z) * std::size_t(d.y) + std::size_t(y0 + y)) * std::size_t(d.x) + std::size_t(x0)) * elem;
        std::memcpy(chunk.data() + ((std::size_t(z) * C + std::size_t(y)) * C) * elem, src, std::size_t(nx) * elem);
      }
    }
    if (all_zero(chunk.data(), chunk.size())) return;  // reads back as the fill value
    std::vector<std::byte> enc = encode(o_.compressor, chunk, int(elem));
    if (shards) {
      // Each (shard, inner chunk) slot is written by exactly one iteration.
      (*shards)[std::size_t((cy / S) * nfx + cx / S)][std::size_t(((cz % S) * S + cy % S) * S + cx % S)] = std::move(enc);
      return;
    }
    write_file(files / std::to_string(cz) / std::to_string(cy) / std::to_string(cx), enc.data(), enc.size());
  });
  if (!shards || (cz % S != S - 1 && z0 + nz != d.z)) return;
  // The layer of shards is complete: write each shard whole (an all-empty one not at all).
  parallel_for(0, nfx * nfy, [&](int i) {
    const std::vector<std::byte> shard = v3::assemble_shard((*shards)[std::size_t(i)]);
    if (!shard.empty()) {
      write_file(files / std::to_string(fz) / std::to_string(i / nfx) / std::to_string(i % nfx), shard.data(), shard.size());
    }
  });
  shards->clear();
}

}  // namespace sl::zarr
