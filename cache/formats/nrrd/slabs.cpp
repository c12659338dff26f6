#include <zlib.h>

#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cstdio>
#include <limits>
#include <memory>
#include <type_traits>
#include <vector>

#include "cache/formats/nrrd/header.h"
#include "cache/formats/nrrd/nrrd.h"
#include "core/util/error.h"

namespace sl {
namespace {

// NRRD, streamed: the header parsed by header.cpp, the data read front to back. gzip data are
// inflated through zlib's gz* stream (byte skip counts decompressed bytes, as teem does).
class NrrdSlabs final : public SlabReader {
 public:
  explicit NrrdSlabs(const std::string& path) : path_(path), h_(nrrd_detail::parse_header(path)) {
    validate_desc(h_.desc, path, std::numeric_limits<std::uint64_t>::max());
    nrrd_detail::DataFile data = nrrd_detail::open_data(h_, path);
    f_ = std::move(data.file);
    where_ = std::move(data.where);
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
      nrrd_detail::swap_bytes(dst, n / std::uint64_t(size), size);
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

}  // namespace

std::unique_ptr<SlabReader> open_nrrd_slabs(const std::string& path) { return std::make_unique<NrrdSlabs>(path); }

}  // namespace sl
