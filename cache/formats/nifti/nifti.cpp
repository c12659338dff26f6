#include "cache/formats/nifti/nifti.h"

#include <fcntl.h>
#include <nifti2_io.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <memory>
#include <mutex>
#include <vector>

#include "core/util/error.h"
#include "core/util/input_file.h"

namespace sl {
namespace {

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// libnifti prints diagnostics on stderr, some whatever its debug level (nifti_image_open's "bad header
// info", nifti_image_read's "short header read"); ours are the one error line (DESIGN.md "Conventions"). So
// while it runs, stderr is /dev/null: NIfTI files are opened and read on the command's own thread,
// and no other thread of this process prints meanwhile (the lock keeps two readers from nesting).
class QuietStderr {
 public:
  QuietStderr() : lock_(mutex()) {
    static const bool once = [] {
      nifti_set_debug_level(0);
      return true;
    }();
    (void)once;
    std::fflush(stderr);
    saved_ = ::dup(2);
    const int null = ::open("/dev/null", O_WRONLY | O_CLOEXEC);
    if (saved_ >= 0 && null >= 0) ::dup2(null, 2);
    if (null >= 0) ::close(null);
  }
  ~QuietStderr() {
    std::fflush(stderr);
    if (saved_ >= 0) {
      ::dup2(saved_, 2);
      ::close(saved_);
    }
  }
  QuietStderr(const QuietStderr&) = delete;
  QuietStderr& operator=(const QuietStderr&) = delete;

 private:
  static std::mutex& mutex() {
    static std::mutex m;
    return m;
  }
  std::lock_guard<std::mutex> lock_;
  int saved_ = -1;
};

struct NiftiImageFree {
  void operator()(nifti_image* n) const { nifti_image_free(n); }
};
using NiftiImage = std::unique_ptr<nifti_image, NiftiImageFree>;

// The header field of type T at byte `offset`, byte-swapped when the file's order is not native.
template <class T> T field_at(const unsigned char* h, int offset, bool swap) {
  T v;
  std::memcpy(&v, h + offset, sizeof v);
  if (swap) {
    auto* b = reinterpret_cast<unsigned char*>(&v);
    std::reverse(b, b + sizeof v);
  }
  return v;
}

// Why libnifti refused `path`: it says only that it did, so the header's first bytes are looked at
// again for the reason the user needs (the reading itself is libnifti's).
std::string why_refused(const std::string& path) {
  gzFile g = gzopen(path.c_str(), "rb");  // plain and gzip files alike
  if (!g) return std::string("cannot open: ") + std::strerror(errno);
  unsigned char h[540] = {};
  const int n = gzread(g, h, sizeof h);
  gzclose(g);
  if (n < 0) return "gzip data are corrupt";
  if (n < 348) return "file is shorter than a NIfTI-1 header (" + std::to_string(n) + " of 348 bytes)";
  const std::int32_t size = field_at<std::int32_t>(h, 0, false), swapped = field_at<std::int32_t>(h, 0, true);
  if (size == 540 || swapped == 540) {
    if (n < 540) return "file is shorter than a NIfTI-2 header (" + std::to_string(n) + " of 540 bytes)";
    if (std::memcmp(h + 4, "n+2", 3) != 0 && std::memcmp(h + 4, "ni2", 3) != 0) {
      return "bad NIfTI-2 magic (expected \"n+2\" or \"ni2\")";
    }
    return "invalid NIfTI-2 header (dim, datatype or vox_offset), or its .img file is missing";
  }
  if (size != 348 && swapped != 348) {
    return "not a NIfTI file (sizeof_hdr is " + std::to_string(size) + ", expected 348 or 540)";
  }
  const bool swap = size != 348;
  if (std::memcmp(h + 344, "ni1", 4) == 0) {
    return "header of a .hdr/.img pair (magic \"ni1\"), but its .img file cannot be read";
  }
  const int ndim = field_at<std::int16_t>(h, 40, swap);
  if (ndim < 1 || ndim > 7) return "dim[0] = " + std::to_string(ndim) + " is out of range 1..7";
  for (int i = 1; i <= ndim; ++i) {
    const int d = field_at<std::int16_t>(h, 40 + 2 * i, swap);
    if (d < 1) return "dim[" + std::to_string(i) + "] = " + std::to_string(d) + " is not positive";
  }
  return "invalid NIfTI-1 header (datatype or vox_offset)";
}

// A NIfTI file opened with libnifti: its header, and its image file positioned at the first voxel.
class NiftiFile {
 public:
  explicit NiftiFile(const std::string& path) {
    check_input_file(path);  // libnifti would block on a FIFO
    const double vox_offset = check_stored_header(path, version_);
    open_image(path, vox_offset);
  }
  ~NiftiFile() { znzclose(file_); }
  NiftiFile(const NiftiFile&) = delete;
  NiftiFile& operator=(const NiftiFile&) = delete;

  const nifti_image& header() const { return *nim_; }
  int version() const { return version_; }  // 1 or 2
  nifti_image* nim() { return nim_.get(); }
  znzFile file() { return file_; }

 private:
  // Reads the header alone and checks it as stored; sets `version` (1 or 2), returns vox_offset.
  static double check_stored_header(const std::string& path, int& version) {
    // The header alone first: libnifti takes a NIfTI-1-sized header with a bad magic for ANALYZE 7.5,
    // which is not NIfTI (and has no orientation); the magic is checked here.
    void* raw = [&] {
      const QuietStderr quiet;
      return nifti_read_header(path.c_str(), &version, 1);
    }();
    if (!raw) throw InputError(path, why_refused(path));
    if (version != 1 && version != 2) {
      std::free(raw);
      throw InputError(path, "header of an unknown NIfTI version (sizeof_hdr matches neither 348 nor 540 with its magic)");
    }
    // Also checked on the header as stored: libnifti quietly repairs non-positive dims (to 1) and a
    // vox_offset inside the header, which would read a volume the file does not describe.
    const auto* h1 = static_cast<const nifti_1_header*>(raw);
    const auto* h2 = static_cast<const nifti_2_header*>(raw);
    char magic[4];
    std::memcpy(magic, version == 2 ? h2->magic : h1->magic, sizeof magic);
    // nifti_read_header returns the header in the file's byte order.
    const auto* bytes = static_cast<const unsigned char*>(raw);
    const std::int32_t size = field_at<std::int32_t>(bytes, 0, false), want = version == 2 ? 540 : 348;
    const bool swap = size != want;
    if (swap && field_at<std::int32_t>(bytes, 0, true) != want) {
      std::free(raw);
      throw InputError(path, "sizeof_hdr " + std::to_string(size) + " does not match its NIfTI-" +
                                 std::to_string(version) + " magic");
    }
    const int dim_at = version == 2 ? 16 : 40;
    std::int64_t dim[8];
    for (int i = 0; i < 8; ++i) {
      dim[i] = version == 2 ? field_at<std::int64_t>(bytes, dim_at + 8 * i, swap) : field_at<std::int16_t>(bytes, dim_at + 2 * i, swap);
    }
    const double vox_offset = version == 2 ? double(field_at<std::int64_t>(bytes, 168, swap)) : double(field_at<float>(bytes, 108, swap));
    std::free(raw);
    const bool pair = magic[1] == 'i';
    if (std::memcmp(magic, version == 2 ? "n+2" : "n+1", 4) != 0 && std::memcmp(magic, version == 2 ? "ni2" : "ni1", 4) != 0) {
      throw InputError(path, version == 2 ? "bad NIfTI-2 magic (expected \"n+2\" or \"ni2\")"
                                          : "bad NIfTI-1 magic (expected \"n+1\" or \"ni1\")");
    }
    if (dim[0] < 1 || dim[0] > 7) throw InputError(path, "dim[0] = " + std::to_string(dim[0]) + " is out of range 1..7");
    for (int i = 1; i <= dim[0]; ++i) {
      if (dim[i] < 1) throw InputError(path, "dim[" + std::to_string(i) + "] = " + std::to_string(dim[i]) + " is not positive");
    }
    const double first = pair ? 0.0 : version == 2 ? 544.0 : 352.0;  // header and extension flag
    if (!(vox_offset >= first) || vox_offset > 1e15) {
      throw InputError(path, "vox_offset " + std::to_string(vox_offset) + " is invalid (at least " +
                                 std::to_string(int(first)) + " in a " + (pair ? ".img" : "single file") + ")");
    }
    return vox_offset;
  }

  // Opens header and image through libnifti, the image file at the first voxel.
  void open_image(const std::string& path, double vox_offset) {
    nifti_image* nim = nullptr;
    char mode[] = "rb";
    {
      const QuietStderr quiet;
      file_ = nifti_image_open(path.c_str(), mode, &nim);
    }
    nim_.reset(nim);
    if (!file_ || !nim_) {
      if (file_) znzclose(file_);
      throw InputError(path, why_refused(path));
    }
    if (double(nim_->iname_offset) != std::floor(vox_offset)) {
      znzclose(file_);
      throw InputError(path, "vox_offset " + std::to_string(vox_offset) + " is invalid");
    }
    // nifti_image_open leaves the image file at its start, not at the first voxel.
    // (znzseek is fseek or gzseek: one returns 0, the other the new offset; both -1 on failure.)
    if (nim_->iname_offset < 0 || znzseek(file_, znz_off_t(nim_->iname_offset), SEEK_SET) < 0) {
      znzclose(file_);
      throw InputError(path, "file ends before vox_offset " + std::to_string(nim_->iname_offset));
    }
  }

  NiftiImage nim_;
  znzFile file_ = nullptr;
  int version_ = 0;
};

bool scaled(const nifti_image& n) {
  return std::isfinite(n.scl_slope) && n.scl_slope != 0.0 && std::isfinite(n.scl_inter) &&
         (n.scl_slope != 1.0 || n.scl_inter != 0.0);
}

VolumeDesc desc_of(const nifti_image& n, const std::string& path) {
  for (int i = 1; i <= 7; ++i) {
    const std::int64_t d = i <= n.dim[0] ? n.dim[i] : 1;
    if (d < 1) throw InputError(path, "dim[" + std::to_string(i) + "] = " + std::to_string(d) + " is not positive");
    if (i > 3 && d != 1) {
      throw InputError(path, "dim[" + std::to_string(i) + "] = " + std::to_string(d) +
                                 ": only 3-D volumes are supported (time series and vectors are not)");
    }
    if (i <= 3 && d > std::numeric_limits<int>::max()) {
      throw InputError(path, "dim[" + std::to_string(i) + "] = " + std::to_string(d) + " is too large");
    }
  }
  VolumeDesc d;
  d.dims = ivec3(int(n.nx), int(n.ny), int(n.nz));
  const double pix[3] = {n.dx, n.dy, n.dz};
  for (int i = 0; i < 3; ++i) {
    const float s = std::fabs(float(pix[i]));
    d.spacing[i] = std::isfinite(s) && s > 0.0f ? s : 1.0f;
  }
  switch (n.datatype) {
    case DT_UINT8: d.type = VoxelType::U8; break;
    case DT_UINT16: d.type = VoxelType::U16; break;
    case DT_UINT32: d.type = VoxelType::U32; break;
    case DT_FLOAT32:
    case DT_INT8:
    case DT_INT16: d.type = VoxelType::F32; break;
    default:
      throw InputError(path, "NIfTI datatype " + std::to_string(n.datatype) + " (" +
                                 nifti_datatype_string(n.datatype) +
                                 ") is not supported (uint8, int8, int16, uint16, uint32, float32)");
  }
  if (scaled(n)) d.type = VoxelType::F32;
  validate_desc(d, path, std::numeric_limits<std::uint64_t>::max());
  return d;
}

template <class In> void scale_to_float(const std::byte* in, std::size_t count, double slope, double inter, float* out) {
  for (std::size_t i = 0; i < count; ++i) {
    In v;
    std::memcpy(&v, in + i * sizeof(In), sizeof v);
    out[i] = float(double(v) * slope + inter);
  }
}

class NiftiSlabs final : public SlabReader {
 public:
  explicit NiftiSlabs(const std::string& path) : path_(path), nifti_(path), desc_(desc_of(nifti_.header(), path)) {
    const nifti_image& n = nifti_.header();
    // An uncompressed image file is checked against the header now, so a short file is refused before
    // anything is read (gzip sizes are known only by reading: read() reports those).
    struct stat st {};
    const std::uint64_t need = std::uint64_t(n.iname_offset) + std::uint64_t(n.nvox) * std::uint64_t(n.nbyper);
    if (n.iname && !ends_with(n.iname, ".gz") && ::stat(n.iname, &st) == 0 && std::uint64_t(st.st_size) < need) {
      throw InputError(path, "data truncated: the header needs " + std::to_string(need) + " bytes, the file " +
                                 (std::string(n.iname) == path ? "has " : "'" + std::string(n.iname) + "' has ") +
                                 std::to_string(st.st_size));
    }
  }
  const VolumeDesc& desc() const override { return desc_; }

  void read(int z0, int nz, std::byte* dst) override {
    const nifti_image& n = nifti_.header();
    const std::size_t count = std::size_t(desc_.dims.x) * std::size_t(desc_.dims.y) * std::size_t(nz);
    const std::size_t in_bytes = count * std::size_t(n.nbyper);
    const bool convert = n.datatype != DT_FLOAT32 && desc_.type == VoxelType::F32;
    const bool apply = scaled(n);
    std::vector<std::byte> tmp;
    std::byte* in = dst;
    if (convert || apply) {
      tmp.resize(in_bytes);
      in = tmp.data();
    }
    // nifti_read_buffer swaps to native order (and zeroes non-finite floats).
    const bool complete = [&] {
      const QuietStderr quiet;
      return nifti_read_buffer(nifti_.file(), in, std::int64_t(in_bytes), nifti_.nim()) == std::int64_t(in_bytes);
    }();
    if (!complete) {
      throw InputError(path_, ends_with(n.iname ? n.iname : "", ".gz")
                                  ? "gzip data are corrupt or truncated at z = " + std::to_string(z0)
                                  : "data truncated at z = " + std::to_string(z0));
    }
    if (!convert && !apply) return;
    const double slope = apply ? n.scl_slope : 1.0, inter = apply ? n.scl_inter : 0.0;
    auto* out = reinterpret_cast<float*>(dst);
    switch (n.datatype) {
      case DT_UINT8: scale_to_float<std::uint8_t>(in, count, slope, inter, out); break;
      case DT_INT8: scale_to_float<std::int8_t>(in, count, slope, inter, out); break;
      case DT_UINT16: scale_to_float<std::uint16_t>(in, count, slope, inter, out); break;
      case DT_INT16: scale_to_float<std::int16_t>(in, count, slope, inter, out); break;
      case DT_UINT32: scale_to_float<std::uint32_t>(in, count, slope, inter, out); break;
      default: scale_to_float<float>(in, count, slope, inter, out); break;
    }
  }

 private:
  std::string path_;
  NiftiFile nifti_;
  VolumeDesc desc_;
};

// The letter of the direction an increasing index runs towards (NIFTI_L2R: towards Right, ...).
char direction_letter(int code) {
  switch (code) {
    case NIFTI_L2R: return 'R';
    case NIFTI_R2L: return 'L';
    case NIFTI_P2A: return 'A';
    case NIFTI_A2P: return 'P';
    case NIFTI_I2S: return 'S';
    case NIFTI_S2I: return 'I';
    default: return '?';
  }
}

std::string xform_name(int code) {
  switch (code) {
    case NIFTI_XFORM_SCANNER_ANAT: return "scanner";
    case NIFTI_XFORM_ALIGNED_ANAT: return "aligned";
    case NIFTI_XFORM_TALAIRACH: return "Talairach";
    case NIFTI_XFORM_MNI_152: return "MNI 152";
    case NIFTI_XFORM_TEMPLATE_OTHER: return "template";
    default: return "code " + std::to_string(code);
  }
}

std::string number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

}  // namespace

std::unique_ptr<SlabReader> open_nifti(const std::string& path) { return std::make_unique<NiftiSlabs>(path); }

bool is_nifti_path(const std::string& path) {
  std::string p = path;
  for (char& c : p) c = char(std::tolower(static_cast<unsigned char>(c)));
  for (const std::string ext : {".nii", ".hdr", ".img"}) {
    if (ends_with(p, ext) || ends_with(p, ext + ".gz")) return true;
  }
  return false;
}

NiftiInfo nifti_info(const std::string& path) {
  const NiftiFile f(path);
  const nifti_image& n = f.header();
  const VolumeDesc d = desc_of(n, path);
  NiftiInfo info;
  // libnifti's nifti_type says one file or two, but in NIfTI-1 codes for NIfTI-2 files too.
  const bool two = n.nifti_type == NIFTI_FTYPE_NIFTI1_2 || n.nifti_type == NIFTI_FTYPE_NIFTI2_2;
  info.format = std::string(f.version() == 2 ? "NIfTI-2" : "NIfTI-1") +
                (two ? ", .hdr/.img pair" : ", single file") + ", " + nifti_datatype_string(n.datatype) + " stored";
  info.scaling = scaled(n) ? "slope " + number(n.scl_slope) + " inter " + number(n.scl_inter) + " (read as " +
                                 to_string(d.type) + ")"
                           : "none";
  // The sform is preferred where both are set: it is the one registration tools write.
  const bool sform = n.sform_code > 0, qform = n.qform_code > 0;
  if (!sform && !qform) {
    info.orientation = "unknown (no qform or sform)";
  } else {
    int i = 0, j = 0, k = 0;
    nifti_dmat44_to_orientation(sform ? n.sto_xyz : n.qto_xyz, &i, &j, &k);
    info.orientation = std::string{direction_letter(i), direction_letter(j), direction_letter(k)} + " (" +
                       (sform ? "sform: " + xform_name(n.sform_code) : "qform: " + xform_name(n.qform_code)) + ")";
  }
  return info;
}

}  // namespace sl
