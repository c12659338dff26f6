#include "core/frame/overlay.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace sl {
namespace {

// 5x7 glyphs, one byte per row, bit 4 = leftmost column.
struct Glyph {
  char c;
  unsigned char rows[7];
};
constexpr Glyph kFont[] = {
    {'0', {0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E}}, {'1', {0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E}},
    {'2', {0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F}}, {'3', {0x1F, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0E}},
    {'4', {0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02}}, {'5', {0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E}},
    {'6', {0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E}}, {'7', {0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08}},
    {'8', {0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E}}, {'9', {0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C}},
    {'.', {0x00, 0x00, 0x00, 0x00, 0x00, 0x0C, 0x0C}}, {' ', {0, 0, 0, 0, 0, 0, 0}},
    {'a', {0x00, 0x00, 0x0E, 0x01, 0x0F, 0x11, 0x0F}}, {'v', {0x00, 0x00, 0x11, 0x11, 0x11, 0x0A, 0x04}},
    {'g', {0x00, 0x0F, 0x11, 0x11, 0x0F, 0x01, 0x0E}}, {'m', {0x00, 0x00, 0x1A, 0x15, 0x15, 0x11, 0x11}},
    {'i', {0x04, 0x00, 0x0C, 0x04, 0x04, 0x04, 0x0E}}, {'n', {0x00, 0x00, 0x16, 0x19, 0x11, 0x11, 0x11}},
    {'x', {0x00, 0x00, 0x11, 0x0A, 0x04, 0x0A, 0x11}}, {'s', {0x00, 0x00, 0x0E, 0x10, 0x0E, 0x01, 0x1E}},
    {'e', {0x00, 0x00, 0x0E, 0x11, 0x1F, 0x10, 0x0E}}, {'o', {0x00, 0x00, 0x0E, 0x11, 0x11, 0x11, 0x0E}},
    {'d', {0x01, 0x01, 0x0D, 0x13, 0x11, 0x11, 0x0F}}, {'t', {0x08, 0x08, 0x1C, 0x08, 0x08, 0x09, 0x06}},
    {'p', {0x00, 0x00, 0x1E, 0x11, 0x1E, 0x10, 0x10}}, {'h', {0x10, 0x10, 0x16, 0x19, 0x11, 0x11, 0x11}},
    {'r', {0x00, 0x00, 0x16, 0x19, 0x10, 0x10, 0x10}}, {'l', {0x0C, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E}},
    {'c', {0x00, 0x00, 0x0E, 0x10, 0x10, 0x11, 0x0E}}, {'y', {0x00, 0x00, 0x11, 0x11, 0x0F, 0x01, 0x0E}},
    {':', {0x00, 0x0C, 0x0C, 0x00, 0x0C, 0x0C, 0x00}}, {'/', {0x00, 0x01, 0x02, 0x04, 0x08, 0x10, 0x00}},
};

void blend(Image& img, int x, int y, const vec4& c) {
  if (x < 0 || y < 0 || x >= img.width || y >= img.height) return;
  vec4& d = img.at(x, y);
  d = c + (1.0f - c.w) * d;  // premultiplied "over"
}

void draw_line(Image& img, vec2 a, vec2 b, const vec4& c) {
  const float len = std::max(std::abs(b.x - a.x), std::abs(b.y - a.y));
  const int n = int(std::ceil(len));
  if (n > 20000) return;  // absurd after projection: skip rather than stall
  for (int i = 0; i <= n; ++i) {
    const vec2 p = n ? a + (b - a) * (float(i) / float(n)) : a;
    blend(img, int(std::floor(p.x)), int(std::floor(p.y)), c);
  }
}

}  // namespace

void draw_text(Image& img, int x, int y, const std::string& text, const vec4& color, int scale) {
  for (char ch : text) {
    const Glyph* g = nullptr;
    for (const Glyph& k : kFont) {
      if (k.c == ch) g = &k;
    }
    if (g) {
      for (int r = 0; r < 7; ++r)
        for (int col = 0; col < 5; ++col)
          if (g->rows[r] & (0x10 >> col))
            for (int sy = 0; sy < scale; ++sy)
              for (int sx = 0; sx < scale; ++sx) blend(img, x + col * scale + sx, y + r * scale + sy, color);
    }
    x += 6 * scale;
  }
}

void draw_depth_complexity(Image& img, float min_dc, float avg_dc, float max_dc) {
  const auto& dc = img.channel("depth_complexity");
  const float scale = max_dc > 0.0f ? 1.0f / max_dc : 0.0f;
  for (std::size_t i = 0; i < img.rgba.size(); ++i) {
    const float v = dc[i] * scale;
    img.rgba[i] = vec4(v, v, v, 1.0f);
  }
  // Legend: a ramp 0..max with the numbers, on a dark backing so it reads over any image.
  const int s = img.height >= 256 ? 2 : 1;
  const int w = std::min(img.width - 8, 160 * s), h = 8 * s;
  const int x0 = 4, y0 = img.height - 4 - h - 12 * s;
  if (w < 16 || y0 < 0) return;
  for (int y = y0 - 2 * s; y < img.height - 2; ++y)
    for (int x = 2; x < x0 + w + 2 && x < img.width; ++x) img.at(x, y) = vec4(0.05f, 0.05f, 0.08f, 1.0f);
  for (int x = 0; x < w; ++x) {
    const float v = float(x) / float(w - 1);
    for (int y = 0; y < h; ++y) img.at(x0 + x, y0 + y) = vec4(v, v, v, 1.0f);
  }
  char buf[96];
  std::snprintf(buf, sizeof buf, "min %.0f avg %.2f max %.0f", min_dc, avg_dc, max_dc);
  draw_text(img, x0, y0 + h + 2 * s, buf, vec4(1.0f, 0.85f, 0.3f, 1.0f), s);
}

void draw_boxes(Image& img, std::span<const OccupancyBox> boxes, const RayGenerator& gen) {
  const float half_w = gen.half_h * gen.aspect;
  auto project = [&](const vec3& p, vec2& out) {
    const vec3 v = p - gen.eye;
    const float z = glm::dot(v, gen.forward);
    float x = glm::dot(v, gen.right), y = glm::dot(v, gen.up);
    if (!gen.orthographic) {
      if (z <= 1e-4f) return false;
      x /= z;
      y /= z;
    }
    out = vec2((x / half_w + 1.0f) * 0.5f * float(gen.width), (1.0f - y / gen.half_h) * 0.5f * float(gen.height));
    return true;
  };
  static const int kEdges[12][2] = {{0, 1}, {2, 3}, {4, 5}, {6, 7}, {0, 2}, {1, 3},
                                    {4, 6}, {5, 7}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};
  for (const OccupancyBox& b : boxes) {
    vec4 c;
    switch (b.cls) {
      case OccupancyClass::Empty: c = vec4(0.9f, 0.1f, 0.1f, 1.0f) * 0.6f; break;
      case OccupancyClass::NonEmpty: c = vec4(0.1f, 0.9f, 0.2f, 1.0f) * 0.6f; break;
      default: c = vec4(0.6f, 0.6f, 0.6f, 1.0f) * 0.6f; break;
    }
    vec2 p[8];
    bool ok[8];
    for (int k = 0; k < 8; ++k) {
      const vec3 corner((k & 1) ? b.box.hi.x : b.box.lo.x, (k & 2) ? b.box.hi.y : b.box.lo.y,
                        (k & 4) ? b.box.hi.z : b.box.lo.z);
      ok[k] = project(corner, p[k]);
    }
    for (const auto& e : kEdges) {
      if (ok[e[0]] && ok[e[1]]) draw_line(img, p[e[0]], p[e[1]], c);
    }
  }
}

}  // namespace sl
