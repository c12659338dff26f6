// Shared by the libFuzzer targets (scripts/fuzz): a private scratch directory for the parsers that
// read files by name (NRRD, NIfTI and TIFF go through stdio, zlib's gzopen and libtiff; a Zarr store
// is a directory), and how one input is cut into the several files a format spans.
#pragma once

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace sl::fuzz {

// The parsers are fed whole volumes only up to this size: a header may claim any size up to the
// machine's memory limit (validate_desc), and allocating that on every run is slowness, not a defect.
inline constexpr std::uint64_t kMaxVolumeBytes = std::uint64_t(16) << 20;

// A directory of this process (tmpfs when there is one, so runs do not wear a disk), emptied before
// every input so nothing of one run leaks into the next, and removed at exit.
class Scratch {
 public:
  Scratch() {
    std::error_code ec;
    const char* tmp = std::getenv("TMPDIR");
    std::string base = std::filesystem::is_directory("/dev/shm", ec) ? "/dev/shm" : tmp ? tmp : "/tmp";
    std::string templ = base + "/sl-fuzz-XXXXXX";
    if (!mkdtemp(templ.data())) {
      std::perror("mkdtemp");
      std::abort();
    }
    dir_ = templ;
  }
  ~Scratch() {
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  const std::filesystem::path& reset() {
    std::error_code ec;
    for (const auto& e : std::filesystem::directory_iterator(dir_, ec)) std::filesystem::remove_all(e.path(), ec);
    return dir_;
  }

 private:
  std::filesystem::path dir_;
};

inline Scratch& scratch() {
  static Scratch s;
  return s;
}

inline void write_file(const std::filesystem::path& p, std::string_view bytes) {
  std::error_code ec;
  if (p.has_parent_path()) std::filesystem::create_directories(p.parent_path(), ec);
  std::FILE* f = std::fopen(p.c_str(), "wb");
  if (!f || std::fwrite(bytes.data(), 1, bytes.size(), f) != bytes.size()) std::abort();  // harness fault
  std::fclose(f);
}

// Splits `s` at the first `max_parts - 1` occurrences of `sep`; the last part keeps the rest (so a
// binary part whose bytes contain `sep` goes last).
inline std::vector<std::string_view> split(std::string_view s, std::string_view sep, std::size_t max_parts) {
  std::vector<std::string_view> parts;
  while (parts.size() + 1 < max_parts) {
    const std::size_t i = s.find(sep);
    if (i == std::string_view::npos) break;
    parts.push_back(s.substr(0, i));
    s.remove_prefix(i + sep.size());
  }
  parts.push_back(s);
  return parts;
}

inline std::string_view as_text(const std::uint8_t* data, std::size_t size) {
  return std::string_view(reinterpret_cast<const char*>(data), size);
}

}  // namespace sl::fuzz
