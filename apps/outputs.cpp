#include "apps/outputs.h"

#include <algorithm>
#include <filesystem>

#include "core/util/atomic_file.h"
#include "core/util/config.h"
#include "core/util/error.h"

namespace sl::app {

std::string output_with_extension(const std::string& prefix, const std::string& ext) {
  return is_stream_file(prefix) ? prefix : prefix + ext;
}

void OutputFiles::add(const std::string& path, std::vector<std::string> also) {
  also.insert(also.begin(), path);
  for (const std::string& f : also) check_output_file(f, path);
  registered_.push_back({path, std::move(also)});
}

void OutputFiles::write(const std::string& path, const std::function<void(const std::string&)>& write) {
  const auto out = std::find_if(registered_.begin(), registered_.end(), [&](const Output& o) { return o.path == path; });
  SL_CHECK(out != registered_.end());
  try {
    write(path);
  } catch (...) {
    for (const std::string& p : written_) {
      std::error_code ec;
      if (!is_stream_file(p)) std::filesystem::remove(p, ec);
    }
    written_.clear();
    throw;
  }
  written_.insert(written_.end(), out->files.begin(), out->files.end());
}

}  // namespace sl::app
