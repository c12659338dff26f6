// Shared by the libFuzzer targets (scripts/fuzz): the entry point, the one rule for what a parser may
// do with bad input (refuse it with an InputError), a private scratch directory for the parsers that
// read files by name (NRRD, NIfTI and TIFF go through stdio, zlib's gzopen and libtiff; a Zarr store
// is a directory), and how one input is cut into the several files a format spans.
#pragma once

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "cache/formats/volume_file.h"
#include "core/util/error.h"

// Defines the target: the block that follows runs once per input, `input` holding its bytes. Whatever
// escapes the block (an exception, an abort on a broken invariant, a sanitizer report) is a finding.
#define SL_FUZZ_TARGET(input)                                                              \
  static void sl_fuzz_one(std::string_view input);                                         \
  extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {      \
    sl_fuzz_one(std::string_view(reinterpret_cast<const char*>(data), size));              \
    return 0;                                                                              \
  }                                                                                        \
  static void sl_fuzz_one(std::string_view input)

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

// What step() returns, or nullopt when it refused the input with an InputError: the one outcome
// allowed for bad input. Any other exception escapes and is a finding.
template <class Step>
auto accepted(Step&& step) -> std::optional<decltype(step())> {
  try {
    return step();
  } catch (const sl::InputError&) {
    return std::nullopt;
  }
}

// `input` as the file `name` in the scratch directory, read whole as render reads a volume file
// (when its header claims at most kMaxVolumeBytes).
inline void read_volume_file(std::string_view input, const std::string& name) {
  const std::string path = (scratch().reset() / name).string();
  write_file(path, input);
  const auto desc = accepted([&] { return sl::read_volume_file_desc(path); });
  if (desc && desc->byte_size() <= kMaxVolumeBytes) accepted([&] { return sl::read_volume_file(path); });
}

}  // namespace sl::fuzz
