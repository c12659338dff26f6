#include "cache/formats/tiff/tiff_stack.h"

#include <tiffio.h>

#include <algorithm>
#include <cstdarg>
#include <cstring>
#include <filesystem>
#include <limits>
#include <mutex>
#include <vector>

#include "core/util/error.h"
#include "core/util/input_file.h"

namespace sl {
namespace {

namespace fs = std::filesystem;

// libtiff reports through process-wide handlers; route errors into the exception of the thread that
// hit them (the last one, which is the most specific), and drop warnings (unknown tags and the like).
thread_local std::string t_tiff_error;
void on_error(const char* module, const char* fmt, va_list ap) {
  char buf[512];
  std::vsnprintf(buf, sizeof buf, fmt, ap);
  t_tiff_error = (module ? std::string(module) + ": " : std::string()) + buf;
}
void on_warning(const char*, const char*, va_list) {}
void install_handlers() {
  static std::once_flag once;
  std::call_once(once, [] {
    TIFFSetErrorHandler(on_error);
    TIFFSetWarningHandler(on_warning);
  });
}

struct TiffCloser {
  void operator()(TIFF* t) const { TIFFClose(t); }
};
using Tiff = std::unique_ptr<TIFF, TiffCloser>;

struct PageFormat {
  int width = 0, height = 0;
  VoxelType type = VoxelType::U8;
};

PageFormat page_format(TIFF* t, const std::string& who) {
  std::uint32_t w = 0, h = 0;
  std::uint16_t bits = 1, spp = 1, fmt = SAMPLEFORMAT_UINT;
  TIFFGetField(t, TIFFTAG_IMAGEWIDTH, &w);
  TIFFGetField(t, TIFFTAG_IMAGELENGTH, &h);
  TIFFGetFieldDefaulted(t, TIFFTAG_BITSPERSAMPLE, &bits);
  TIFFGetFieldDefaulted(t, TIFFTAG_SAMPLESPERPIXEL, &spp);
  TIFFGetFieldDefaulted(t, TIFFTAG_SAMPLEFORMAT, &fmt);
  if (w < 1 || h < 1 || w > (1u << 24) || h > (1u << 24)) throw InputError(who, "bad image size");
  if (spp != 1) throw InputError(who, std::to_string(spp) + " samples per pixel; only grayscale is supported");
  PageFormat f{int(w), int(h), VoxelType::U8};
  if (fmt == SAMPLEFORMAT_UINT && bits == 8) f.type = VoxelType::U8;
  else if (fmt == SAMPLEFORMAT_UINT && bits == 16) f.type = VoxelType::U16;
  else if (fmt == SAMPLEFORMAT_IEEEFP && bits == 32) f.type = VoxelType::F32;
  else {
    throw InputError(who, std::to_string(bits) + "-bit " + (fmt == SAMPLEFORMAT_INT ? "signed" : fmt == SAMPLEFORMAT_IEEEFP ? "float" : "unsigned") +
                              " samples are not supported (8/16-bit unsigned or 32-bit float)");
  }
  return f;
}

// Throws InputError(who, what), with libtiff's last error of this thread when it reported one.
[[noreturn]] void fail(const std::string& who, const std::string& what) {
  throw InputError(who, what + (t_tiff_error.empty() ? "" : " (" + t_tiff_error + ")"));
}

void read_tiles(TIFF* t, const PageFormat& f, std::byte* dst, const std::string& who) {
  const std::size_t elem = std::size_t(voxel_size(f.type));
  std::uint32_t tw = 0, th = 0;
  TIFFGetField(t, TIFFTAG_TILEWIDTH, &tw);
  TIFFGetField(t, TIFFTAG_TILELENGTH, &th);
  // Checked before the tile buffer is allocated: a corrupt tile width would make it gigabytes for a
  // small page. A tile covers at most the page rounded up to libtiff's 16-pixel tile grid, or 4096
  // pixels (writers use 256-1024 whatever the page size); and a 2-D grayscale tile is exactly tw x th
  // samples (no tile depth).
  const auto plausible = [](std::uint32_t tile, int page) {
    return tile > 0 && tile <= std::max<std::uint32_t>(4096, (std::uint32_t(page) + 15) / 16 * 16);
  };
  if (!plausible(tw, f.width) || !plausible(th, f.height) || TIFFTileSize64(t) != std::uint64_t(tw) * th * elem) {
    fail(who, "bad tile size " + std::to_string(tw) + "x" + std::to_string(th) + " for a " + std::to_string(f.width) +
                  "x" + std::to_string(f.height) + " page");
  }
  std::vector<std::byte> tile(std::size_t(tw) * th * elem);
  for (std::uint32_t y0 = 0; y0 < std::uint32_t(f.height); y0 += th) {
    for (std::uint32_t x0 = 0; x0 < std::uint32_t(f.width); x0 += tw) {
      if (TIFFReadTile(t, tile.data(), x0, y0, 0, 0) < 0) fail(who, "cannot read a tile");
      const std::uint32_t nx = std::min(tw, std::uint32_t(f.width) - x0), ny = std::min(th, std::uint32_t(f.height) - y0);
      for (std::uint32_t y = 0; y < ny; ++y) {
        std::memcpy(dst + (std::size_t(y0 + y) * std::size_t(f.width) + x0) * elem, tile.data() + std::size_t(y) * tw * elem,
                    std::size_t(nx) * elem);
      }
    }
  }
}

void read_scanlines(TIFF* t, const PageFormat& f, std::byte* dst, const std::string& who) {
  const std::size_t elem = std::size_t(voxel_size(f.type));
  if (std::size_t(TIFFScanlineSize(t)) != std::size_t(f.width) * elem) fail(who, "unexpected scanline size");
  for (int y = 0; y < f.height; ++y) {
    if (TIFFReadScanline(t, dst + std::size_t(y) * std::size_t(f.width) * elem, std::uint32_t(y), 0) < 0) {
      fail(who, "cannot read row " + std::to_string(y));
    }
  }
}

// Reads the current page into dst (width * height voxels, x fastest).
void read_page(TIFF* t, const PageFormat& f, std::byte* dst, const std::string& who) {
  t_tiff_error.clear();
  if (TIFFIsTiled(t)) {
    read_tiles(t, f, dst, who);
  } else {
    read_scanlines(t, f, dst, who);
  }
}

Tiff open_tiff(const std::string& file) {
  t_tiff_error.clear();
  check_input_file(file);  // libtiff would block on a FIFO
  Tiff t(TIFFOpen(file.c_str(), "r"));
  if (!t) fail(file, "cannot open as TIFF");
  return t;
}

class TiffStack final : public SlabReader {
 public:
  explicit TiffStack(const std::string& path) : path_(path) {
    install_handlers();
    std::error_code ec;
    if (fs::is_directory(path, ec)) {
      for (const auto& e : fs::directory_iterator(path, ec)) {
        std::string ext = e.path().extension().string();
        for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
        // Whatever is not a directory is listed: a FIFO, device or symlink loop among the slices is then
        // refused by name when it is opened (open_tiff), not skipped or thrown as a filesystem error.
        std::error_code fec;
        if ((ext == ".tif" || ext == ".tiff") && !e.is_directory(fec)) files_.push_back(e.path().string());
      }
      if (ec) throw InputError(path, "cannot list directory: " + ec.message());
      if (files_.empty()) throw InputError(path, "directory holds no .tif/.tiff files");
      std::sort(files_.begin(), files_.end());
      Tiff t = open_tiff(files_[0]);
      fmt_ = page_format(t.get(), files_[0]);
      depth_ = int(files_.size());
    } else {
      multipage_ = open_tiff(path);
      fmt_ = page_format(multipage_.get(), path);
      const tdir_t n = TIFFNumberOfDirectories(multipage_.get());
      if (n < 1) throw InputError(path, "no pages");
      depth_ = int(n);
    }
    desc_.dims = ivec3(fmt_.width, fmt_.height, depth_);
    desc_.type = fmt_.type;
    validate_desc(desc_, path, std::numeric_limits<std::uint64_t>::max());
  }

  const VolumeDesc& desc() const override { return desc_; }

  void read(int z0, int nz, std::byte* dst) override {
    const std::size_t plane = std::size_t(fmt_.width) * std::size_t(fmt_.height) * std::size_t(voxel_size(fmt_.type));
    for (int z = z0; z < z0 + nz; ++z, dst += plane) {
      if (multipage_) {
        if (z > 0 && !TIFFReadDirectory(multipage_.get())) throw InputError(path_, "page " + std::to_string(z) + " is missing");
        check_same(page_format(multipage_.get(), path_), path_ + " page " + std::to_string(z));
        read_page(multipage_.get(), fmt_, dst, path_ + " page " + std::to_string(z));
      } else {
        const std::string& f = files_[std::size_t(z)];
        Tiff t = open_tiff(f);
        check_same(page_format(t.get(), f), f);
        read_page(t.get(), fmt_, dst, f);
      }
    }
  }

 private:
  void check_same(const PageFormat& f, const std::string& who) const {
    if (f.width != fmt_.width || f.height != fmt_.height || f.type != fmt_.type) {
      throw InputError(who, "slice is " + std::to_string(f.width) + "x" + std::to_string(f.height) + " " + to_string(f.type) +
                                ", the first is " + std::to_string(fmt_.width) + "x" + std::to_string(fmt_.height) + " " +
                                to_string(fmt_.type));
    }
  }

  std::string path_;
  std::vector<std::string> files_;
  Tiff multipage_;
  PageFormat fmt_;
  int depth_ = 0;
  VolumeDesc desc_;
};

}  // namespace

std::unique_ptr<SlabReader> open_tiff_stack(const std::string& path) { return std::make_unique<TiffStack>(path); }

}  // namespace sl
