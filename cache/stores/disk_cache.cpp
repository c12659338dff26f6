#include "cache/stores/disk_cache.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <vector>

#include "core/util/checked.h"
#include "core/util/error.h"

namespace sl {
namespace {

namespace fs = std::filesystem;

constexpr char kMagic[8] = {'S', 'L', 'D', 'C', 'A', 'C', 'H', '1'};
constexpr std::size_t kHeader = 8 + 8 + 8 + 4;  // magic, key length, payload length, CRC-32
constexpr const char* kTmp = ".tmp.";            // in temporary names only (ENTRY.tmp.PID.SERIAL)

std::string hash_name(const std::string& key) {
  std::uint64_t h = 1469598103934665603ull;  // FNV-1a 64
  for (unsigned char c : key) h = (h ^ c) * 1099511628211ull;
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", (unsigned long long)h);
  return buf;
}

// The marker's whole content: a folder with this file is a cache this program made.
constexpr char kMarkerText[] = "sparseleap disk cache 1\n";

bool is_entry_name(const std::string& n) {
  return n.size() == 16 && std::all_of(n.begin(), n.end(), [](char c) { return std::isxdigit((unsigned char)c); });
}
bool all_digits(const std::string& s) {
  return !s.empty() && std::all_of(s.begin(), s.end(), [](char c) { return std::isdigit((unsigned char)c); });
}
// ENTRY.tmp.PID.SERIAL, as put() names its temporaries.
bool is_tmp_name(const std::string& n) {
  if (n.size() < 16 + 5 || !is_entry_name(n.substr(0, 16)) || n.compare(16, 5, kTmp) != 0) return false;
  const std::string rest = n.substr(21);
  const auto dot = rest.find('.');
  return dot != std::string::npos && all_digits(rest.substr(0, dot)) && all_digits(rest.substr(dot + 1));
}

// Opens a file for reading without following a symlink or blocking on a FIFO; -1 unless regular.
int open_regular(const std::string& p) {
  const int fd = ::open(p.c_str(), O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) return -1;
  struct stat s {};
  if (::fstat(fd, &s) != 0 || !S_ISREG(s.st_mode)) {
    ::close(fd);
    return -1;
  }
  return fd;
}

bool read_exact(int fd, void* dst, std::size_t n) {
  auto* p = static_cast<char*>(dst);
  while (n > 0) {
    const ssize_t r = ::read(fd, p, n);
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) return false;
    p += r;
    n -= std::size_t(r);
  }
  return true;
}

bool has_magic(const std::string& p) {
  const int fd = open_regular(p);
  if (fd < 0) return false;
  char m[8];
  const bool ok = read_exact(fd, m, 8) && std::memcmp(m, kMagic, 8) == 0;
  ::close(fd);
  return ok;
}

std::uint32_t checksum(const std::string& key, const std::byte* p, std::size_t n) {
  uLong c = crc32(0L, reinterpret_cast<const Bytef*>(key.data()), uInt(key.size()));
  // zlib takes uInt lengths: feed large payloads in pieces.
  for (std::size_t done = 0; done < n;) {
    const std::size_t step = std::min<std::size_t>(n - done, std::size_t(1) << 30);
    c = crc32(c, reinterpret_cast<const Bytef*>(p + done), uInt(step));
    done += step;
  }
  return std::uint32_t(c);
}

void put_u64(std::vector<char>& h, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) h.push_back(char((v >> (8 * i)) & 0xff));
}
std::uint64_t get_u64(const unsigned char* p) {
  std::uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}

}  // namespace

DiskCache::DiskCache(std::string dir, std::uint64_t max_bytes)
    : dir_(std::move(dir)), entries_(dir_ + "/" + kEntriesName), max_bytes_(max_bytes) {
  adopt();
  scan();
}

void DiskCache::adopt() {
  const auto fail = [&](const std::string& why) { throw InputError("--disk-cache", dir_ + ": " + why); };
  std::error_code ec;
  const fs::file_status st = fs::status(dir_, ec);  // DIR itself may be a symlink the user made
  if (fs::exists(st) && !fs::is_directory(st)) fail("not a directory");
  if (!fs::exists(st)) {
    fs::create_directories(dir_, ec);
    if (!fs::is_directory(dir_, ec)) fail("cannot create the directory" + (ec ? " (" + ec.message() + ")" : ""));
  }
  if (::access(dir_.c_str(), W_OK | X_OK) != 0) fail(std::string("the directory is not writable (") + std::strerror(errno) + ")");
  const std::string marker = dir_ + "/" + kMarkerName;
  const auto is_marker = [&] {
    // O_NOFOLLOW | O_NONBLOCK: a symlink or a FIFO in the marker's place is not our marker.
    const int fd = ::open(marker.c_str(), O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) return false;
    struct stat s {};
    char buf[sizeof kMarkerText] = {};
    const bool ok = ::fstat(fd, &s) == 0 && S_ISREG(s.st_mode) && std::uint64_t(s.st_size) == sizeof kMarkerText - 1 &&
                    ::read(fd, buf, sizeof buf) == ssize_t(sizeof kMarkerText - 1) &&
                    std::memcmp(buf, kMarkerText, sizeof kMarkerText - 1) == 0;
    ::close(fd);
    return ok;
  };
  if (fs::symlink_status(marker, ec).type() == fs::file_type::not_found) {
    // Only an empty folder becomes a cache: the cache deletes what it holds.
    bool empty = true;
    for (auto it = fs::directory_iterator(dir_, ec); !ec && it != fs::directory_iterator(); it.increment(ec)) empty = false;
    if (ec) fail("cannot list the directory (" + ec.message() + ")");
    if (!empty) {
      // Another process may have just made DIR a cache: then its marker is there now (checked below).
      if (fs::symlink_status(marker, ec).type() == fs::file_type::not_found) {
        fail("holds files and is not a sparseleap disk cache (no " + std::string(kMarkerName) +
             "); give a new or empty folder");
      }
    } else if (const int fd = ::open(marker.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0644);
               fd >= 0) {
      const bool ok = ::write(fd, kMarkerText, sizeof kMarkerText - 1) == ssize_t(sizeof kMarkerText - 1);
      ::close(fd);
      if (!ok) fail("cannot write " + std::string(kMarkerName));
    } else if (errno != EEXIST) {  // EEXIST: another process made the cache meanwhile (checked below)
      fail("cannot write " + std::string(kMarkerName) + " (" + std::strerror(errno) + ")");
    }
  }
  if (!is_marker()) fail(std::string(kMarkerName) + " is not a sparseleap disk cache's marker; give a new or empty folder");
  const fs::file_status es = fs::symlink_status(entries_, ec);
  if (es.type() == fs::file_type::not_found) {
    fs::create_directory(entries_, ec);
    ec.clear();  // another process may have made it: checked next
  }
  if (fs::symlink_status(entries_, ec).type() != fs::file_type::directory) {
    fail(std::string(kEntriesName) + " is not a directory of the cache's own (a file or a symlink)");
  }
  if (::access(entries_.c_str(), W_OK | X_OK) != 0) {
    fail(std::string(kEntriesName) + " is not writable (" + std::strerror(errno) + ")");
  }
}

void DiskCache::scan() {
  struct Found {
    std::string name;
    std::uint64_t size;
    fs::file_time_type time;
  };
  std::vector<Found> found;
  std::error_code ec;
  for (auto it = fs::directory_iterator(entries_, ec); !ec && it != fs::directory_iterator(); it.increment(ec)) {
    const std::string name = it->path().filename().string();
    // symlink_status: a symlink is never followed, indexed or deleted.
    if (!it->is_regular_file(ec) || it->is_symlink(ec)) {
      ec.clear();
      continue;
    }
    if (is_tmp_name(name)) {
      fs::remove(it->path(), ec);  // a write a crash interrupted
      ec.clear();
      continue;
    }
    if (!is_entry_name(name) || !has_magic(it->path().string())) continue;  // not ours: never touched
    found.push_back({name, std::uint64_t(it->file_size(ec)), it->last_write_time(ec)});
    ec.clear();
  }
  if (ec) throw InputError("--disk-cache", entries_ + ": cannot list the directory (" + ec.message() + ")");
  std::sort(found.begin(), found.end(), [](const Found& a, const Found& b) { return a.time < b.time; });
  std::lock_guard lock(mutex_);
  for (const Found& f : found) insert_locked(f.name, f.size);  // oldest first: the newest ends in front
}

void DiskCache::remove_entry_file(const std::string& name) const {
  struct stat s {};
  if (::lstat(path(name).c_str(), &s) == 0 && S_ISREG(s.st_mode)) ::unlink(path(name).c_str());
}

void DiskCache::insert_locked(const std::string& name, std::uint64_t size) {
  erase_locked(name);
  lru_.push_front(name);
  index_[name] = {lru_.begin(), size};
  bytes_ += size;
  while (bytes_ > max_bytes_ && lru_.size() > 1) {
    const std::string victim = lru_.back();
    erase_locked(victim);
    remove_entry_file(victim);
    counters_.evicted.fetch_add(1, std::memory_order_relaxed);
  }
}

void DiskCache::erase_locked(const std::string& name) {
  const auto it = index_.find(name);
  if (it == index_.end()) return;
  bytes_ -= it->second.size;
  lru_.erase(it->second.lru);
  index_.erase(it);
}

std::uint64_t DiskCache::bytes() const {
  std::lock_guard lock(mutex_);
  return bytes_;
}

std::size_t DiskCache::files() const {
  std::lock_guard lock(mutex_);
  return index_.size();
}

std::optional<std::vector<std::byte>> DiskCache::get(const std::string& key) {
  const std::string name = hash_name(key);
  {
    std::lock_guard lock(mutex_);
    const auto it = index_.find(name);
    if (it == index_.end()) {
      counters_.misses.fetch_add(1, std::memory_order_relaxed);
      return std::nullopt;
    }
    lru_.splice(lru_.begin(), lru_, it->second.lru);
  }
  // `ours`: the file is still the cache's (its magic): a torn or corrupt entry is deleted; anything
  // else put in its place is only forgotten.
  const auto bad = [&](bool corrupt, bool ours) -> std::optional<std::vector<std::byte>> {
    (corrupt ? counters_.corrupt : counters_.misses).fetch_add(1, std::memory_order_relaxed);
    if (corrupt) {
      std::lock_guard lock(mutex_);
      erase_locked(name);
      if (ours) remove_entry_file(name);
    }
    return std::nullopt;
  };
  const int fd = open_regular(path(name));
  if (fd < 0) return bad(true, false);
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  unsigned char h[kHeader];
  if (!read_exact(fd, h, 8) || std::memcmp(h, kMagic, 8) != 0) return bad(true, false);
  if (!read_exact(fd, h + 8, kHeader - 8)) return bad(true, true);
  const std::uint64_t key_len = get_u64(h + 8), len = get_u64(h + 16);
  std::uint32_t crc = 0;
  for (int i = 3; i >= 0; --i) crc = (crc << 8) | h[24 + i];
  struct stat st {};
  if (::fstat(fd, &st) != 0) return bad(true, true);
  const std::uint64_t size = std::uint64_t(st.st_size);
  if (size < kHeader || key_len > size - kHeader || len != size - kHeader - key_len) return bad(true, true);
  std::string stored_key(key_len, '\0');
  std::vector<std::byte> payload(len);
  if (!read_exact(fd, stored_key.data(), key_len) || !read_exact(fd, payload.data(), len) ||
      checksum(stored_key, payload.data(), payload.size()) != crc) {
    return bad(true, true);
  }
  if (stored_key != key) return bad(false, true);  // a hash collision: the other key's entry stays
  ::futimens(fd, nullptr);  // the LRU order a restart rebuilds
  counters_.hits.fetch_add(1, std::memory_order_relaxed);
  return payload;
}

void DiskCache::put(const std::string& key, const std::vector<std::byte>& payload) {
  const std::uint64_t size = kHeader + key.size() + payload.size();
  if (size > max_bytes_) return;
  const std::string name = hash_name(key);
  const std::string tmp = path(name) + kTmp + std::to_string(::getpid()) + "." +
                          std::to_string(tmp_serial_.fetch_add(1, std::memory_order_relaxed));
  std::vector<char> h(kMagic, kMagic + 8);
  put_u64(h, key.size());
  put_u64(h, payload.size());
  const std::uint32_t crc = checksum(key, payload.data(), payload.size());
  for (int i = 0; i < 4; ++i) h.push_back(char((crc >> (8 * i)) & 0xff));
  // O_EXCL | O_NOFOLLOW: never writes through a file or symlink that was there already.
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0644);
  if (fd < 0) {
    counters_.write_failures.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  const auto write_all = [&](const void* src, std::size_t n) {
    const auto* p = static_cast<const char*>(src);
    while (n > 0) {
      const ssize_t w = ::write(fd, p, n);
      if (w < 0 && errno == EINTR) continue;
      if (w <= 0) return false;
      p += w;
      n -= std::size_t(w);
    }
    return true;
  };
  const bool ok = write_all(h.data(), h.size()) && write_all(key.data(), key.size()) &&
                  write_all(payload.data(), payload.size());
  const bool closed = ::close(fd) == 0;
  std::error_code ec;
  if (!ok || !closed || (fs::rename(tmp, path(name), ec), ec)) {
    ::unlink(tmp.c_str());
    counters_.write_failures.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  std::lock_guard lock(mutex_);
  insert_locked(name, size);
}

template <class Fetch>
std::optional<std::vector<std::byte>> CachedByteStore::through(const std::string& cache_key, Fetch fetch) const {
  if (std::optional<std::vector<std::byte>> hit = cache_->get(cache_key)) return hit;
  std::optional<std::vector<std::byte>> v = fetch();
  if (v) cache_->put(cache_key, *v);
  return v;
}

std::optional<std::vector<std::byte>> CachedByteStore::read(const std::string& key, std::uint64_t max_bytes) const {
  std::optional<std::vector<std::byte>> r = through(name_ + "/" + key, [&] { return inner_->read(key, max_bytes); });
  if (r) checked_bound(r->size(), max_bytes, "object");
  return r;
}

std::optional<std::vector<std::byte>> CachedByteStore::read_range(const std::string& key, std::uint64_t offset,
                                                                  std::uint64_t n) const {
  return through(name_ + "/" + key + "#" + std::to_string(offset) + "+" + std::to_string(n),
                 [&] { return inner_->read_range(key, offset, n); });
}

std::optional<std::vector<std::byte>> CachedByteStore::read_suffix(const std::string& key, std::uint64_t n) const {
  return through(name_ + "/" + key + "#-" + std::to_string(n), [&] { return inner_->read_suffix(key, n); });
}

}  // namespace sl
