// Rendered frames and their files: EXR (linear premultiplied RGBA + extra float channels) and PNG
// (the same over black, sRGB-encoded), both written to a temporary name and renamed when complete.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "core/util/math.h"

namespace sl {

struct Image {
  int width = 0;
  int height = 0;
  std::vector<vec4> rgba;                              // row 0 = top, premultiplied, linear
  std::map<std::string, std::vector<float>> channels;  // extra per-pixel channels ("samples", ...)

  Image() = default;
  Image(int w, int h) : width(w), height(h), rgba(std::size_t(w) * std::size_t(h), vec4(0.0f)) {}
  vec4& at(int x, int y) { return rgba[std::size_t(y) * width + x]; }
  const vec4& at(int x, int y) const { return rgba[std::size_t(y) * width + x]; }
  std::vector<float>& channel(const std::string& name) {
    auto& c = channels[name];
    c.resize(std::size_t(width) * std::size_t(height), 0.0f);
    return c;
  }
};

float linear_to_srgb(float x);

// Throws InputError(path, ...) when the file cannot be written; never leaves a partial file.
void write_exr(const std::string& path, const Image& img);
void write_png(const std::string& path, const Image& img);
// Reads an EXR written by write_exr (or any RGBA float/half EXR); InputError on failure.
Image read_exr(const std::string& path);
// Reads an 8-bit RGB/RGBA PNG into rgba (values 0..1, not linearised); for tests and tools.
Image read_png(const std::string& path);

// Fails early, before a long render, when `prefix`'s directory cannot be written.
void check_output_prefix(const std::string& prefix);

}  // namespace sl
