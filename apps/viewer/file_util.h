// Writing the viewer's small text outputs (transfer functions, camera paths) without ever leaving a
// partial file behind: write to a temporary name, then rename (DESIGN.md §10).
#pragma once

#include <string>

namespace sl::viewer {

// Throws InputError(path, reason) when the file cannot be written.
void write_text_file_atomic(const std::string& path, const std::string& text);

}  // namespace sl::viewer
