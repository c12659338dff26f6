#include "cache/formats/nifti.h"

#include <zlib.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <type_traits>
#include <vector>

#include "core/error.h"

namespace sl {
namespace {

constexpr int kHeaderSize = 348;

template <class T> T get(const unsigned char* h, int offset, bool swap) {
  T v;
  std::memcpy(&v, h + offset, sizeof v);
  if (swap) {
    auto* b = reinterpret_cast<unsigned char*>(&v);
    std::reverse(b, b + sizeof v);
  }
  return v;
}

void swap_bytes(std::byte* p, std::size_t count, int size) {
  for (std::size_t i = 0; i < count; ++i, p += size) std::reverse(p, p + size);
}

class NiftiSlabs final : public SlabReader {
 public:
  explicit NiftiSlabs(const std::string& path) : path_(path) {
    // gz* reads plain files transparently, so .nii and .nii.gz share one path.
    gz_.reset(gzopen(path.c_str(), "rb"));
    if (!gz_) throw InputError(path, std::string("cannot open: ") + std::strerror(errno));
    gzbuffer(gz_.get(), 1 << 20);
    unsigned char h[kHeaderSize];
    if (gzread(gz_.get(), h, kHeaderSize) != kHeaderSize) throw InputError(path, "file is shorter than a NIfTI-1 header");
    const std::int32_t size = get<std::int32_t>(h, 0, false);
    if (size == 540 || get<std::int32_t>(h, 0, true) == 540) throw InputError(path, "NIfTI-2 is not supported");
    if (size == kHeaderSize) {
      swap_ = false;
    } else if (get<std::int32_t>(h, 0, true) == kHeaderSize) {
      swap_ = true;
    } else {
      throw InputError(path, "not a NIfTI-1 file (sizeof_hdr is not 348)");
    }
    if (std::memcmp(h + 344, "ni1", 4) == 0) {
      throw InputError(path, "a NIfTI .hdr/.img pair is not supported; convert it to a single .nii");
    }
    if (std::memcmp(h + 344, "n+1", 4) != 0) throw InputError(path, "bad NIfTI-1 magic (expected \"n+1\")");
    const int ndim = get<std::int16_t>(h, 40, swap_);
    if (ndim < 1 || ndim > 7) throw InputError(path, "dim[0] = " + std::to_string(ndim) + " is out of range 1..7");
    int dims[7];
    for (int i = 0; i < 7; ++i) dims[i] = i < ndim ? get<std::int16_t>(h, 42 + 2 * i, swap_) : 1;
    for (int i = 0; i < 7; ++i) {
      if (dims[i] < 1) throw InputError(path, "dim[" + std::to_string(i + 1) + "] = " + std::to_string(dims[i]) + " is not positive");
      if (i >= 3 && dims[i] != 1) {
        throw InputError(path, "dim[" + std::to_string(i + 1) + "] = " + std::to_string(dims[i]) +
                                   ": only 3-D volumes are supported (time series and vectors are not)");
      }
    }
    desc_.dims = ivec3(dims[0], dims[1], dims[2]);
    for (int i = 0; i < 3; ++i) {
      const float s = std::fabs(get<float>(h, 80 + 4 * i, swap_));
      desc_.spacing[i] = std::isfinite(s) && s > 0.0f ? s : 1.0f;
    }
    datatype_ = get<std::int16_t>(h, 70, swap_);
    switch (datatype_) {
      case 2: desc_.type = VoxelType::U8; in_size_ = 1; break;
      case 512: desc_.type = VoxelType::U16; in_size_ = 2; break;
      case 768: desc_.type = VoxelType::U32; in_size_ = 4; break;
      case 16: desc_.type = VoxelType::F32; in_size_ = 4; break;
      case 4: desc_.type = VoxelType::F32; in_size_ = 2; break;  // int16, converted
      default:
        throw InputError(path, "NIfTI datatype " + std::to_string(datatype_) +
                                   " is not supported (uint8, int16, uint16, uint32, float32)");
    }
    validate_desc(desc_, path, std::numeric_limits<std::uint64_t>::max());
    const float off = get<float>(h, 108, swap_);
    if (!(off >= float(kHeaderSize)) || off > 1e9f) throw InputError(path, "vox_offset " + std::to_string(off) + " is invalid");
    for (long left = long(off) - kHeaderSize; left > 0;) {  // the extension area, skipped
      char buf[4096];
      const int n = gzread(gz_.get(), buf, unsigned(std::min<long>(left, long(sizeof buf))));
      if (n <= 0) throw InputError(path, "file ends before vox_offset");
      left -= n;
    }
  }

  const VolumeDesc& desc() const override { return desc_; }

  void read(int z0, int nz, std::byte* dst) override {
    const std::size_t count = std::size_t(desc_.dims.x) * std::size_t(desc_.dims.y) * std::size_t(nz);
    std::vector<std::byte> tmp;
    std::byte* in = dst;
    if (datatype_ == 4) {
      tmp.resize(count * 2);
      in = tmp.data();
    }
    const std::size_t n = count * std::size_t(in_size_);
    for (std::size_t done = 0; done < n;) {
      const int got = gzread(gz_.get(), in + done, unsigned(std::min<std::size_t>(n - done, std::size_t(1) << 30)));
      if (got <= 0) {
        int err = 0;
        const char* msg = gzerror(gz_.get(), &err);
        throw InputError(path_, err != Z_OK && err != Z_BUF_ERROR
                                    ? std::string("gzip data are corrupt (") + msg + ")"
                                    : "data truncated at z = " + std::to_string(z0 + int(done / (n / std::size_t(nz)))));
      }
      done += std::size_t(got);
    }
    if (in_size_ > 1 && swap_) swap_bytes(in, count, in_size_);
    if (datatype_ == 4) {
      const auto* s = reinterpret_cast<const std::int16_t*>(in);
      auto* d = reinterpret_cast<float*>(dst);
      for (std::size_t i = 0; i < count; ++i) d[i] = float(s[i]);
    }
  }

 private:
  std::string path_;
  // Owned through a deleter so that a constructor that throws still closes it.
  struct GzCloser {
    void operator()(gzFile f) const { gzclose(f); }
  };
  std::unique_ptr<std::remove_pointer_t<gzFile>, GzCloser> gz_;
  bool swap_ = false;
  int datatype_ = 0;
  int in_size_ = 1;
  VolumeDesc desc_;
};

}  // namespace

std::unique_ptr<SlabReader> open_nifti(const std::string& path) { return std::make_unique<NiftiSlabs>(path); }

}  // namespace sl
