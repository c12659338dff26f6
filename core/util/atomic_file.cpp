#include "core/util/atomic_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <system_error>

#include "core/util/error.h"

namespace sl {
namespace fs = std::filesystem;

namespace {

fs::file_type type_of(const fs::path& p) {
  std::error_code ec;
  return fs::status(p, ec).type();
}

bool is_stream(fs::file_type t) { return t == fs::file_type::character || t == fs::file_type::fifo; }

// Why an existing `p` must not be written; empty when it is absent, a regular file or a stream.
std::string not_writable(const fs::path& p) {
  std::error_code ec;
  const fs::file_status s = fs::status(p, ec);
  switch (s.type()) {
    case fs::file_type::not_found:
    case fs::file_type::regular:
    case fs::file_type::character:
    case fs::file_type::fifo: return {};
    case fs::file_type::directory: return "it is a directory, not a regular file";
    case fs::file_type::block: return "it is a block device, not a regular file";
    case fs::file_type::socket: return "it is a socket, not a regular file";
    default: return ec ? ec.message() : "it is not a regular file";
  }
}

[[noreturn]] void fail_write(const fs::path& path, const std::string& who, const std::string& why) {
  // Built with append: GCC 12 warns falsely (-Wrestrict) on `"'" + std::string`.
  std::string reason = "cannot write ";
  if (who == path.string()) {
    reason.append("file");
  } else {
    reason.append(1, '\'').append(path.string()).append(1, '\'');
  }
  throw InputError(who, reason.append(": ").append(why));
}

}  // namespace

AtomicFile::AtomicFile(fs::path path, std::string who) : path_(std::move(path)), who_(std::move(who)) {
  if (who_.empty()) who_ = path_.string();
  if (const std::string why = not_writable(path_); !why.empty()) fail(why);
  const fs::file_type type = type_of(path_);
  if (is_stream(type)) {
    // In place. O_NONBLOCK: opening a FIFO nobody reads fails (ENXIO) instead of waiting forever.
    stream_ = true;
    temp_ = path_;
    const bool fifo = type == fs::file_type::fifo;
    const int fd = ::open(path_.c_str(), O_WRONLY | O_CLOEXEC | (fifo ? O_NONBLOCK : 0));
    if (fd < 0) fail(fifo && errno == ENXIO ? "it is a FIFO without a reader" : std::strerror(errno));
    if (fifo) ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) & ~O_NONBLOCK);
    file_ = ::fdopen(fd, "wb");
    if (!file_) {
      const int err = errno;
      ::close(fd);
      fail(std::strerror(err));
    }
    return;
  }
  static std::atomic<unsigned> counter{0};
  const fs::path dir = path_.has_parent_path() ? path_.parent_path() : fs::path(".");
  // Hidden and suffixed: never mistaken for the finished file. (Built with append: GCC 12 warns
  // falsely, -Wrestrict, on `"." + std::string`.)
  std::string name(1, '.');
  name.append(path_.filename().string()).append(".part-").append(std::to_string(::getpid()));
  name.append("-").append(std::to_string(counter++));
  temp_ = dir / name;
  // O_EXCL: a temporary of another writer is never shared or truncated.
  const int fd = ::open(temp_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
  if (fd < 0) fail(std::strerror(errno));
  file_ = ::fdopen(fd, "wb");
  if (!file_) {
    const int err = errno;
    ::close(fd);
    std::error_code ec;
    fs::remove(temp_, ec);
    fail(std::strerror(err));
  }
}

AtomicFile::~AtomicFile() {
  if (file_) std::fclose(file_);
  if (!committed_ && !stream_) {  // a stream is the user's device or pipe: never removed
    std::error_code ec;
    fs::remove(temp_, ec);
  }
}

void AtomicFile::fail(const std::string& why) const { fail_write(path_, who_, why); }

void AtomicFile::write(const void* data, std::size_t n) {
  if (!file_) fail("written after close");
  if (n && std::fwrite(data, 1, n, file_) != n) fail(std::strerror(errno));
}

void AtomicFile::close() {
  if (!file_) return;
  std::FILE* f = file_;
  file_ = nullptr;
  // A device or pipe has nothing to sync (fsync fails with EINVAL there); its write errors surface
  // in the flush.
  const bool flushed = std::fflush(f) == 0 && (stream_ || ::fsync(::fileno(f)) == 0);
  const int err = errno;
  if (std::fclose(f) != 0 || !flushed) fail(std::strerror(flushed ? errno : err));
}

void AtomicFile::commit() {
  close();
  if (stream_) {
    committed_ = true;
    return;
  }
  if (const std::string why = not_writable(path_); !why.empty()) fail(why);
  if (is_stream(type_of(path_))) fail("a device or FIFO appeared there while writing");
  std::error_code ec;
  fs::rename(temp_, path_, ec);
  if (ec) fail(ec.message());
  committed_ = true;
}

void write_file_atomic(const std::string& path, std::string_view bytes) {
  AtomicFile f(path);
  f.write(bytes);
  f.commit();
}

void check_output_file(const fs::path& path, const std::string& who_given) {
  const std::string who = who_given.empty() ? path.string() : who_given;
  if (path.empty()) throw InputError(who, "empty output file name");
  if (const std::string why = not_writable(path); !why.empty()) fail_write(path, who, why);
  const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
  std::error_code ec;
  if (is_stream(type_of(path))) {
    if (::access(path.c_str(), W_OK) != 0) fail_write(path, who, std::strerror(errno));
  } else if (!fs::is_directory(dir, ec)) {
    fail_write(path, who, "folder '" + dir.string() + "' does not exist");
  } else if (::access(dir.c_str(), W_OK) != 0) {
    fail_write(path, who, "folder '" + dir.string() + "' is not writable");
  }
}

bool is_stream_file(const fs::path& path) { return is_stream(type_of(path)); }

}  // namespace sl
