#include "cache/stores/byte_store.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace sl {
namespace {

struct Fd {
  int fd = -1;
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
};

// Opens root/key; false when it does not exist.
bool open_object(const std::string& path, Fd& f, std::uint64_t& size) {
  f.fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (f.fd < 0) {
    if (errno == ENOENT) return false;
    throw std::runtime_error(std::string("cannot read: ") + std::strerror(errno));
  }
  struct stat st {};
  if (::fstat(f.fd, &st) != 0) throw std::runtime_error(std::string("cannot stat: ") + std::strerror(errno));
  size = std::uint64_t(st.st_size);
  return true;
}

std::vector<std::byte> pread_all(int fd, std::uint64_t offset, std::uint64_t n) {
  std::vector<std::byte> out(n);
  std::uint64_t done = 0;
  while (done < n) {
    const ssize_t r = ::pread(fd, out.data() + done, n - done, off_t(offset + done));
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) throw std::runtime_error(std::string("read error: ") + std::strerror(errno));
    if (r == 0) throw std::runtime_error("file ended early (read " + std::to_string(done) + " of " + std::to_string(n) + " bytes)");
    done += std::uint64_t(r);
  }
  return out;
}

}  // namespace

std::optional<std::vector<std::byte>> LocalByteStore::read(const std::string& key) const {
  Fd f;
  std::uint64_t size = 0;
  if (!open_object(root_ + "/" + key, f, size)) return std::nullopt;
  return pread_all(f.fd, 0, size);
}

std::optional<std::vector<std::byte>> LocalByteStore::read_range(const std::string& key, std::uint64_t offset,
                                                                 std::uint64_t n) const {
  Fd f;
  std::uint64_t size = 0;
  if (!open_object(root_ + "/" + key, f, size)) return std::nullopt;
  if (offset > size || n > size - offset) {
    throw std::runtime_error("byte range " + std::to_string(offset) + "+" + std::to_string(n) +
                             " lies past the end of the " + std::to_string(size) + "-byte file");
  }
  return pread_all(f.fd, offset, n);
}

std::optional<std::vector<std::byte>> LocalByteStore::read_suffix(const std::string& key, std::uint64_t n) const {
  Fd f;
  std::uint64_t size = 0;
  if (!open_object(root_ + "/" + key, f, size)) return std::nullopt;
  if (n > size) {
    throw std::runtime_error("file has " + std::to_string(size) + " bytes, fewer than the " + std::to_string(n) +
                             "-byte shard index");
  }
  return pread_all(f.fd, size - n, n);
}

std::optional<std::uint64_t> LocalByteStore::size_if_known(const std::string& key) const {
  struct stat st {};
  if (::stat((root_ + "/" + key).c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return std::nullopt;
  return std::uint64_t(st.st_size);
}

}  // namespace sl
