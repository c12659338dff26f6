#include "core/atomic_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <system_error>

#include "core/error.h"

namespace sl {
namespace fs = std::filesystem;

namespace {

// Why an existing `p` must not be replaced; empty when it is absent or a regular file.
std::string not_replaceable(const fs::path& p) {
  std::error_code ec;
  const fs::file_status s = fs::status(p, ec);
  switch (s.type()) {
    case fs::file_type::not_found:
    case fs::file_type::regular: return {};
    case fs::file_type::directory: return "it is a directory, not a regular file";
    case fs::file_type::fifo: return "it is a FIFO, not a regular file";
    case fs::file_type::character: return "it is a character device, not a regular file";
    case fs::file_type::block: return "it is a block device, not a regular file";
    case fs::file_type::socket: return "it is a socket, not a regular file";
    default: return ec ? ec.message() : "it is not a regular file";
  }
}

}  // namespace

AtomicFile::AtomicFile(fs::path path, std::string who) : path_(std::move(path)), who_(std::move(who)) {
  if (who_.empty()) who_ = path_.string();
  if (const std::string why = not_replaceable(path_); !why.empty()) fail(why);
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
  if (!committed_) {
    std::error_code ec;
    fs::remove(temp_, ec);
  }
}

void AtomicFile::fail(const std::string& why) const {
  // Built with append: GCC 12 warns falsely (-Wrestrict) on `"'" + std::string`.
  std::string reason = "cannot write ";
  if (who_ == path_.string()) {
    reason.append("file");
  } else {
    reason.append(1, '\'').append(path_.string()).append(1, '\'');
  }
  throw InputError(who_, reason.append(": ").append(why));
}

void AtomicFile::write(const void* data, std::size_t n) {
  if (!file_) fail("written after close");
  if (n && std::fwrite(data, 1, n, file_) != n) fail(std::strerror(errno));
}

void AtomicFile::close() {
  if (!file_) return;
  std::FILE* f = file_;
  file_ = nullptr;
  const bool flushed = std::fflush(f) == 0 && ::fsync(::fileno(f)) == 0;
  const int err = errno;
  if (std::fclose(f) != 0 || !flushed) fail(std::strerror(flushed ? errno : err));
}

void AtomicFile::commit() {
  close();
  if (const std::string why = not_replaceable(path_); !why.empty()) fail(why);
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

}  // namespace sl
