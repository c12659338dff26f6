// Saving what the window shows: 8-bit RGBA pixels (already display values, so no colour conversion)
// to a PNG, through a temporary name so a failed write never leaves a file that looks complete.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace sl::viewer {

// `rgba` holds width * height * 4 bytes, row 0 at the top. `bottom_up`: rows come from glReadPixels
// (row 0 at the bottom) and are flipped. Throws InputError(path, ...) on failure.
void write_png_rgba8(const std::string& path, int width, int height, const std::vector<std::uint8_t>& rgba,
                     bool bottom_up = false);

// "sparseleap-view-001.png", "-002", ...: the first name in `dir` not yet taken (the S key).
std::string next_screenshot_name(const std::string& dir);

}  // namespace sl::viewer
