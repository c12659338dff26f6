#include "cache/formats/volume_file.h"

#include <algorithm>
#include <cctype>
#include <filesystem>

#include "cache/formats/nifti/nifti.h"
#include "cache/formats/nrrd/nrrd.h"
#include "cache/formats/tiff/tiff_stack.h"
#include "core/util/error.h"

namespace sl {
namespace {

namespace fs = std::filesystem;

std::string lower(std::string s) {
  for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

bool ends_with(const std::string& s, const std::string& e) {
  return s.size() >= e.size() && s.compare(s.size() - e.size(), e.size(), e) == 0;
}

}  // namespace

std::unique_ptr<SlabReader> open_slab_reader(const std::string& path) {
  const std::string p = lower(path);
  std::error_code ec;
  if (fs::is_directory(path, ec)) return open_tiff_stack(path);
  if (!fs::exists(path, ec)) throw InputError(path, "no such file or directory");
  if (ends_with(p, ".nrrd") || ends_with(p, ".nhdr")) return open_nrrd_slabs(path);
  if (ends_with(p, ".tif") || ends_with(p, ".tiff")) return open_tiff_stack(path);
  if (is_nifti_path(p)) return open_nifti(path);
  throw InputError(path, "unknown input format (expected .nrrd/.nhdr, .tif/.tiff or a directory of them, "
                         ".nii/.nii.gz or .hdr/.img)");
}

bool is_slab_volume_path(const std::string& path) {
  const std::string p = lower(path);
  std::error_code ec;
  return is_nifti_path(p) || ends_with(p, ".tif") || ends_with(p, ".tiff") ||
         fs::is_directory(path, ec);
}

VolumeDesc read_volume_file_desc(const std::string& path) {
  if (!is_slab_volume_path(path)) return read_nrrd_header(path);
  return open_slab_reader(path)->desc();
}

Volume read_volume_file(const std::string& path) {
  if (!is_slab_volume_path(path)) return read_nrrd(path);
  const std::unique_ptr<SlabReader> r = open_slab_reader(path);
  Volume v(r->desc(), path);
  const VolumeDesc& d = r->desc();
  const std::size_t plane = std::size_t(d.dims.x) * std::size_t(d.dims.y) * std::size_t(voxel_size(d.type));
  constexpr int kSlab = 16;  // z-planes per read: the readers stream, so any slab size works
  for (int z = 0; z < d.dims.z; z += kSlab) {
    const int nz = std::min(kSlab, d.dims.z - z);
    r->read(z, nz, v.data() + std::size_t(z) * plane);
  }
  return v;
}

}  // namespace sl
