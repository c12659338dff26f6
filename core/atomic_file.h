// Writing a file so that it is either complete under its name or absent: never partial output left
// looking complete (DESIGN.md §12). The bytes go to a hidden temporary in the same folder (so the
// rename stays on one file system), are flushed and fsync'ed, and the temporary is renamed over the
// destination only then. Every writer of the project uses this: images, stats, bench CSV/JSON, NRRD,
// screenshots, transfer functions and camera paths.
#pragma once

#include <cstddef>
#include <cstdio>
#include <filesystem>
#include <string>
#include <string_view>

namespace sl {

class AtomicFile {
 public:
  // Creates the temporary ".NAME.part-PID-N" beside `path`. Refuses a destination that exists and is
  // not a regular file (a directory, /dev/null, a FIFO): renaming over it would replace or break it.
  // Errors are InputError(who, "cannot write ...: reason"); `who` is the name the user gave (default
  // `path`), e.g. the header of a detached NRRD whose data file this is.
  explicit AtomicFile(std::filesystem::path path, std::string who = {});
  ~AtomicFile();  // removes the temporary unless committed
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  const std::filesystem::path& path() const { return path_; }
  // For libraries that open the file by name themselves (OpenEXR, libpng's simplified API): they
  // truncate and write the same file, which close() then syncs.
  const std::filesystem::path& temp_path() const { return temp_; }
  // The open temporary, for libraries that write to a FILE* (libpng); null after close().
  std::FILE* stream() { return file_; }
  void write(const void* data, std::size_t n);
  void write(std::string_view text) { write(text.data(), text.size()); }

  // Flushes, fsyncs and closes, so errors such as a full disk surface before anything is renamed and
  // a crash after the rename cannot leave the name on an empty or partial file.
  void close();
  // close() if still open, then renames the temporary over path() (checked again: still no directory,
  // device or FIFO there).
  void commit();

 private:
  [[noreturn]] void fail(const std::string& why) const;
  std::filesystem::path path_, temp_;
  std::string who_;
  std::FILE* file_ = nullptr;
  bool committed_ = false;
};

// The whole file at once: `bytes` exactly as given.
void write_file_atomic(const std::string& path, std::string_view bytes);

}  // namespace sl
