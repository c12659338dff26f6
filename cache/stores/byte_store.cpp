#include "cache/stores/byte_store.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <climits>
#include <cstdlib>
#include <cstring>
#include <stdexcept>

#include "cache/stores/store_key.h"
#include "core/util/checked.h"
#include "core/util/input_file.h"

namespace sl {
namespace {

struct Fd {
  int fd = -1;
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
};

// Opens `key` of the store at `root`; false when it does not exist. Not a regular file, or a file whose
// resolved path leaves the root (a symlink out of the store), is refused.
bool open_object(const std::string& root, const std::string& canonical_root, const std::string& key, Fd& f,
                 std::uint64_t& size) {
  const std::string path = local_store_path(root, key);
  f.fd = open_input_fd(path);
  if (f.fd < 0) return false;
  std::string where;
  // A root that did not resolve when the store was made (created since) is resolved now.
  char buf[PATH_MAX];
  const std::string canon = !canonical_root.empty() ? canonical_root : ::realpath(root.c_str(), buf) ? std::string(buf) : root;
  if (!fd_inside(f.fd, canon, &where)) {
    throw std::runtime_error("'" + printable_key(key) + "' resolves to '" + where + "', outside the store");
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

LocalByteStore::LocalByteStore(std::string root) : root_(std::move(root)) {
  char buf[PATH_MAX];
  if (::realpath(root_.c_str(), buf)) canonical_root_ = buf;
}

std::optional<std::vector<std::byte>> LocalByteStore::read(const std::string& key, std::uint64_t max_bytes) const {
  Fd f;
  std::uint64_t size = 0;
  if (!open_object(root_, canonical_root_, key, f, size)) return std::nullopt;
  checked_bound(size, max_bytes, "file");
  return pread_all(f.fd, 0, size);
}

std::optional<std::vector<std::byte>> LocalByteStore::read_range(const std::string& key, std::uint64_t offset,
                                                                 std::uint64_t n) const {
  Fd f;
  std::uint64_t size = 0;
  if (!open_object(root_, canonical_root_, key, f, size)) return std::nullopt;
  if (offset > size || n > size - offset) {
    throw std::runtime_error("byte range " + std::to_string(offset) + "+" + std::to_string(n) +
                             " lies past the end of the " + std::to_string(size) + "-byte file");
  }
  return pread_all(f.fd, offset, n);
}

std::optional<std::vector<std::byte>> LocalByteStore::read_suffix(const std::string& key, std::uint64_t n) const {
  Fd f;
  std::uint64_t size = 0;
  if (!open_object(root_, canonical_root_, key, f, size)) return std::nullopt;
  if (n > size) {
    throw std::runtime_error("file has " + std::to_string(size) + " bytes, fewer than the " + std::to_string(n) +
                             "-byte shard index");
  }
  return pread_all(f.fd, size - n, n);
}

std::optional<std::uint64_t> LocalByteStore::size_if_known(const std::string& key) const {
  std::string path;
  try {
    path = local_store_path(root_, key);
  } catch (const std::runtime_error&) {
    return std::nullopt;  // a key that could leave the store: read() refuses it, naming it
  }
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return std::nullopt;
  return std::uint64_t(st.st_size);
}

}  // namespace sl
