#include "apps/viewer/screenshot.h"

#include <png.h>

#include <cstdio>
#include <filesystem>

#include "core/util/atomic_file.h"
#include "core/util/error.h"

namespace sl::viewer {

void write_png_rgba8(const std::string& path, int width, int height, const std::vector<std::uint8_t>& rgba,
                     bool bottom_up) {
  if (width <= 0 || height <= 0 || rgba.size() != std::size_t(width) * std::size_t(height) * 4) {
    throw InputError(path, "screenshot has no pixels");
  }
  png_image img{};
  img.version = PNG_IMAGE_VERSION;
  img.width = png_uint_32(width);
  img.height = png_uint_32(height);
  img.format = PNG_FORMAT_RGBA;
  // A negative row stride makes libpng read rows bottom-up: the GL read-back needs no copy.
  const png_int_32 stride = png_int_32(PNG_IMAGE_ROW_STRIDE(img)) * (bottom_up ? -1 : 1);
  AtomicFile out(path);
  if (!png_image_write_to_stdio(&img, out.stream(), 0, rgba.data(), stride, nullptr)) {
    throw InputError(path, std::string("cannot write PNG: ") + img.message);
  }
  out.commit();
}

std::string next_screenshot_name(const std::string& dir) {
  const std::filesystem::path base = dir.empty() ? std::filesystem::path(".") : std::filesystem::path(dir);
  for (int i = 1; i < 100000; ++i) {
    char name[64];
    std::snprintf(name, sizeof name, "sparseleap-view-%03d.png", i);
    const std::filesystem::path p = base / name;
    if (!std::filesystem::exists(p)) return p.string();
  }
  return (base / "sparseleap-view.png").string();
}

}  // namespace sl::viewer
