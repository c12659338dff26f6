#include "apps/viewer/file_util.h"

#include <filesystem>
#include <fstream>

#include "core/error.h"

namespace sl::viewer {

void write_text_file_atomic(const std::string& path, const std::string& text) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp, std::ios::binary);
    if (!(f << text << '\n')) {
      std::error_code ignored;
      std::filesystem::remove(tmp, ignored);
      throw InputError(path, "cannot write file");
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::filesystem::remove(tmp, ec);
    throw InputError(path, "cannot write file: " + ec.message());
  }
}

}  // namespace sl::viewer
