#include "cache/formats/zarr_writer.h"

#include <bit>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/parallel.h"

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
  write_group(dir_, "image", false);
  if (o_.label_type) {
    fs::create_directory(dir_ / "labels", ec);
    const std::string g = "{\n  \"zarr_format\": 2\n}\n";
    write_file(dir_ / "labels" / ".zgroup", g.data(), g.size());
    const std::string attrs = json{{"labels", {"labels"}}}.dump(2) + "\n";
    write_file(dir_ / "labels" / ".zattrs", attrs.data(), attrs.size());
    fs::create_directory(dir_ / "labels" / "labels", ec);
    if (ec) throw InputError(who_, "cannot create '" + (dir_ / "labels").string() + "': " + ec.message());
    write_group(dir_ / "labels" / "labels", "labels", true);
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

// One multiscale group: .zgroup, .zattrs (NGFF 0.4 multiscales: axes z, y, x in the spacing's unit-
// less space, per-level scale = spacing * 2^l) and each level's .zarray.
void StoreWriter::write_group(const fs::path& group, const std::string& name, bool labels) const {
  const std::string g = "{\n  \"zarr_format\": 2\n}\n";
  write_file(group / ".zgroup", g.data(), g.size());
  json datasets = json::array();
  for (int l = 0; l < o_.levels; ++l) {
    const float f = float(1 << l);
    const json scale = {double(desc_.spacing.z * f), double(desc_.spacing.y * f), double(desc_.spacing.x * f)};
    datasets.push_back({{"path", std::to_string(l)},
                        {"coordinateTransformations", json::array({{{"type", "scale"}, {"scale", scale}}})}});
  }
  json ms = {{"version", "0.4"},
             {"name", name},
             {"axes", json::array({{{"name", "z"}, {"type", "space"}},
                                   {{"name", "y"}, {"type", "space"}},
                                   {{"name", "x"}, {"type", "space"}}})},
             {"datasets", datasets},
             {"type", labels ? "mode" : "mean"},
             {"metadata", {{"method", "sparseleap 2x reduction (DESIGN.md section 3)"}}}};
  json attrs = {{"multiscales", json::array({ms})}};
  if (labels) attrs["image-label"] = {{"version", "0.4"}, {"source", {{"image", "../../"}}}};
  const std::string a = attrs.dump(2) + "\n";
  write_file(group / ".zattrs", a.data(), a.size());
  for (int l = 0; l < o_.levels; ++l) {
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
    const std::string z = to_json(m).dump(2) + "\n";
    write_file(group / std::to_string(l) / ".zarray", z.data(), z.size());
  }
}

void StoreWriter::set_max_label(std::uint32_t max_label) {
  SL_CHECK(o_.label_type.has_value());
  const fs::path p = dir_ / "labels" / "labels" / ".zattrs";
  std::FILE* f = std::fopen(p.c_str(), "rb");
  std::string text;
  if (f) {
    char buf[4096];
    for (std::size_t n; (n = std::fread(buf, 1, sizeof buf, f)) > 0;) text.append(buf, n);
    std::fclose(f);
  }
  json attrs = json::parse(text);
  attrs["sparseleap"] = {{"max_label", max_label}};
  const std::string a = attrs.dump(2) + "\n";
  write_file(p, a.data(), a.size());
}

void StoreWriter::write_slab(bool labels, int level, int z0, int nz, const std::byte* data) {
  SL_CHECK(level >= 0 && level < o_.levels && (!labels || o_.label_type));
  const ivec3 d = level_dims(level);
  const int C = o_.chunk;
  SL_CHECK(z0 % C == 0 && nz >= 1 && z0 + nz <= d.z && (nz == C || z0 + nz == d.z));
  const VoxelType t = labels ? *o_.label_type : desc_.type;
  const std::size_t elem = std::size_t(voxel_size(t));
  const fs::path arr = (labels ? dir_ / "labels" / "labels" : dir_) / std::to_string(level);
  const int cz = z0 / C;
  const int ncx = (d.x + C - 1) / C, ncy = (d.y + C - 1) / C;
  std::error_code ec;
  for (int cy = 0; cy < ncy; ++cy) {
    fs::create_directories(arr / std::to_string(cz) / std::to_string(cy), ec);
    if (ec) throw InputError(who_, "cannot create '" + arr.string() + "/...': " + ec.message());
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
    const std::vector<std::byte> enc = encode(o_.compressor, chunk, int(elem));
    write_file(arr / std::to_string(cz) / std::to_string(cy) / std::to_string(cx), enc.data(), enc.size());
  });
}

}  // namespace sl::zarr
