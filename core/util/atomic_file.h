// Writing a file so that it is either complete under its name or absent: never partial output left
// looking complete (DESIGN.md "Conventions"). The bytes go to a hidden temporary in the same folder (so the
// rename stays on one file system), are flushed and fsync'ed, and the temporary is renamed over the
// destination only then. Every writer of the project uses this: images, stats, bench CSV/JSON, NRRD,
// screenshots, transfer functions and camera paths.
//
// A destination that is a character device or a FIFO (/dev/null, /dev/stdout, a pipe) is a stream,
// not a file to replace: it is written in place, never renamed over, and a write error there (ENOSPC
// of /dev/full, a FIFO without a reader) is reported naming it. Directories, block devices and
// sockets are refused.
#pragma once

#include <cstddef>
#include <cstdio>
#include <filesystem>
#include <string>
#include <string_view>

namespace sl {

class AtomicFile {
 public:
  // Creates the temporary ".NAME.part-PID-N" beside `path`, or opens `path` itself when it is a
  // stream (above). Refuses a destination that exists and is neither a regular file nor a stream (a
  // directory, a block device, a socket): renaming over it would replace or break it.
  // Errors are InputError(who, "cannot write ...: reason"); `who` is the name the user gave (default
  // `path`), e.g. the header of a detached NRRD whose data file this is.
  explicit AtomicFile(std::filesystem::path path, std::string who = {});
  ~AtomicFile();  // removes the temporary unless committed
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  const std::filesystem::path& path() const { return path_; }
  // For libraries that open the file by name themselves (OpenEXR, libpng's simplified API): they
  // truncate and write the same file, which close() then syncs. A stream's own path.
  const std::filesystem::path& temp_path() const { return temp_; }
  // The open temporary, for libraries that write to a FILE* (libpng); null after close().
  std::FILE* stream() { return file_; }
  void write(const void* data, std::size_t n);
  void write(std::string_view text) { write(text.data(), text.size()); }

  // Flushes, fsyncs and closes, so errors such as a full disk surface before anything is renamed and
  // a crash after the rename cannot leave the name on an empty or partial file.
  void close();
  // close() if still open, then renames the temporary over path() (checked again: still no directory
  // or device there); a stream is only closed.
  void commit();

 private:
  [[noreturn]] void fail(const std::string& why) const;
  std::filesystem::path path_, temp_;
  std::string who_;
  std::FILE* file_ = nullptr;
  bool stream_ = false;  // written in place (a character device or FIFO)
  bool committed_ = false;
};

// The whole file at once: `bytes` exactly as given.
void write_file_atomic(const std::string& path, std::string_view bytes);

// Throws the InputError that AtomicFile(path, who) would, without writing anything: the folder is
// missing or not writable, or `path` is a directory, a block device or a socket. Commands check all
// their outputs with it before the (slow) work, so that a bad second output cannot leave a complete
// first one behind.
void check_output_file(const std::filesystem::path& path, const std::string& who = {});

// True when `path` exists and is a character device or a FIFO: written in place, never replaced.
bool is_stream_file(const std::filesystem::path& path);

}  // namespace sl
