#include "core/util/image.h"

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <png.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>

#include "core/util/atomic_file.h"
#include "core/util/error.h"

namespace sl {

float linear_to_srgb(float x) {
  x = std::clamp(x, 0.0f, 1.0f);
  return x <= 0.0031308f ? 12.92f * x : 1.055f * std::pow(x, 1.0f / 2.4f) - 0.055f;
}

void check_output_prefix(const std::string& prefix) {
  std::filesystem::path p(prefix);
  std::filesystem::path dir = p.parent_path().empty() ? std::filesystem::path(".") : p.parent_path();
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec)) {
    throw InputError(prefix, "output directory '" + dir.string() + "' does not exist");
  }
  if (::access(dir.c_str(), W_OK) != 0) {
    throw InputError(prefix, "output directory '" + dir.string() + "' is not writable");
  }
}

void write_exr(const std::string& path, const Image& img) {
  AtomicFile out(path);
  try {
    Imf::Header header(img.width, img.height);
    header.compression() = Imf::ZIP_COMPRESSION;
    const char* names[4] = {"R", "G", "B", "A"};
    for (const char* n : names) header.channels().insert(n, Imf::Channel(Imf::FLOAT));
    for (const auto& [name, data] : img.channels) header.channels().insert(name, Imf::Channel(Imf::FLOAT));
    Imf::FrameBuffer fb;
    char* base = const_cast<char*>(reinterpret_cast<const char*>(img.rgba.data()));
    for (int c = 0; c < 4; ++c) {
      fb.insert(names[c], Imf::Slice(Imf::FLOAT, base + c * sizeof(float), sizeof(vec4),
                                     sizeof(vec4) * std::size_t(img.width)));
    }
    for (const auto& [name, data] : img.channels) {
      fb.insert(name, Imf::Slice(Imf::FLOAT, const_cast<char*>(reinterpret_cast<const char*>(data.data())),
                                 sizeof(float), sizeof(float) * std::size_t(img.width)));
    }
    Imf::OutputFile file(out.temp_path().c_str(), header);
    file.setFrameBuffer(fb);
    file.writePixels(img.height);
  } catch (const std::exception& e) {
    throw InputError(path, std::string("cannot write EXR: ") + e.what());
  }
  out.commit();
}

Image read_exr(const std::string& path) {
  try {
    Imf::InputFile file(path.c_str());
    const Imath::Box2i dw = file.header().dataWindow();
    const int w = dw.max.x - dw.min.x + 1;
    const int h = dw.max.y - dw.min.y + 1;
    if (w <= 0 || h <= 0 || std::int64_t(w) * h > (std::int64_t(1) << 30)) {
      throw InputError(path, "invalid EXR data window");
    }
    Image img(w, h);
    Imf::FrameBuffer fb;
    char* base = reinterpret_cast<char*>(img.rgba.data()) -
                 (std::size_t(dw.min.x) + std::size_t(dw.min.y) * w) * sizeof(vec4);
    const char* names[4] = {"R", "G", "B", "A"};
    for (int c = 0; c < 4; ++c) {
      fb.insert(names[c], Imf::Slice(Imf::FLOAT, base + c * sizeof(float), sizeof(vec4),
                                     sizeof(vec4) * std::size_t(w), 1, 1, c == 3 ? 1.0 : 0.0));
    }
    for (auto it = file.header().channels().begin(); it != file.header().channels().end(); ++it) {
      const std::string name = it.name();
      if (name == "R" || name == "G" || name == "B" || name == "A") continue;
      auto& data = img.channel(name);
      char* cb = reinterpret_cast<char*>(data.data()) -
                 (std::size_t(dw.min.x) + std::size_t(dw.min.y) * w) * sizeof(float);
      fb.insert(name, Imf::Slice(Imf::FLOAT, cb, sizeof(float), sizeof(float) * std::size_t(w)));
    }
    file.setFrameBuffer(fb);
    file.readPixels(dw.min.y, dw.max.y);
    return img;
  } catch (const InputError&) {
    throw;
  } catch (const std::exception& e) {
    throw InputError(path, std::string("cannot read EXR: ") + e.what());
  }
}

namespace {

// libpng's own stdio writer turns a failed fwrite into "libpng error: Write Error" printed on stderr
// and drops errno; this one keeps the reason (ENOSPC of a full disk or /dev/full) for the one error
// line (DESIGN.md "Conventions") and prints nothing itself.
struct PngSink {
  std::FILE* file = nullptr;
  int error = 0;        // errno of the write that failed
  std::string message;  // libpng's reason otherwise
};

void png_sink_write(png_structp png, png_bytep data, std::size_t n) {
  auto* s = static_cast<PngSink*>(png_get_io_ptr(png));
  if (std::fwrite(data, 1, n, s->file) != n) {
    s->error = errno;
    png_error(png, "write error");
  }
}

void png_sink_flush(png_structp png) {
  auto* s = static_cast<PngSink*>(png_get_io_ptr(png));
  if (std::fflush(s->file) != 0) {
    s->error = errno;
    png_error(png, "write error");
  }
}

[[noreturn]] void png_sink_error(png_structp png, png_const_charp message) {
  static_cast<PngSink*>(png_get_error_ptr(png))->message = message;
  png_longjmp(png, 1);
}

void png_sink_warning(png_structp, png_const_charp) {}

}  // namespace

void write_png(const std::string& path, const Image& img) {
  AtomicFile out(path);
  PngSink sink{out.stream(), 0, {}};
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &sink, png_sink_error, png_sink_warning);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  std::vector<unsigned char> row(std::size_t(img.width) * 3);
  volatile bool ok = png && info;  // volatile: survives libpng's longjmp
  if (ok && setjmp(png_jmpbuf(png))) ok = false;
  if (ok) {
    png_set_write_fn(png, &sink, png_sink_write, png_sink_flush);
    png_set_IHDR(png, info, img.width, img.height, 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_set_sRGB(png, info, PNG_sRGB_INTENT_PERCEPTUAL);
    png_write_info(png, info);
    for (int y = 0; y < img.height; ++y) {
      for (int x = 0; x < img.width; ++x) {
        const vec4& c = img.at(x, y);  // premultiplied over black: the colour is the composite
        for (int k = 0; k < 3; ++k) {
          row[std::size_t(x) * 3 + k] = (unsigned char)std::lround(255.0f * linear_to_srgb(c[k]));
        }
      }
      png_write_row(png, row.data());
    }
    png_write_end(png, nullptr);
  }
  png_destroy_write_struct(png ? &png : nullptr, info ? &info : nullptr);
  if (!ok) {
    // No message: libpng could not even allocate its structures.
    const std::string why = sink.error ? std::strerror(sink.error) : sink.message.empty() ? "out of memory" : sink.message;
    throw InputError(path, "cannot write PNG: " + why);
  }
  out.commit();
}

Image read_png(const std::string& path) {
  png_image pimg{};
  pimg.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&pimg, path.c_str())) {
    throw InputError(path, std::string("cannot read PNG: ") + pimg.message);
  }
  pimg.format = PNG_FORMAT_RGBA;
  std::vector<unsigned char> buf(PNG_IMAGE_SIZE(pimg));
  if (!png_image_finish_read(&pimg, nullptr, buf.data(), 0, nullptr)) {
    throw InputError(path, std::string("cannot read PNG: ") + pimg.message);
  }
  Image img(int(pimg.width), int(pimg.height));
  for (std::size_t i = 0; i < img.rgba.size(); ++i) {
    img.rgba[i] = vec4(buf[4 * i], buf[4 * i + 1], buf[4 * i + 2], buf[4 * i + 3]) / 255.0f;
  }
  return img;
}

}  // namespace sl
