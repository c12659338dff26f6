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
#include <fstream>
#include <vector>

#include "core/util/checked.h"
#include "core/util/error.h"

namespace sl {
namespace {

namespace fs = std::filesystem;

constexpr char kMagic[8] = {'S', 'L', 'D', 'C', 'A', 'C', 'H', '1'};
constexpr std::size_t kHeader = 8 + 8 + 8 + 4;  // magic, key length, payload length, CRC-32
constexpr const char* kTmp = ".tmp.";            // in temporary names only

std::string hash_name(const std::string& key) {
  std::uint64_t h = 1469598103934665603ull;  // FNV-1a 64
  for (unsigned char c : key) h = (h ^ c) * 1099511628211ull;
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", (unsigned long long)h);
  return buf;
}

bool is_entry_name(const std::string& n) {
  return n.size() == 16 && std::all_of(n.begin(), n.end(), [](char c) { return std::isxdigit((unsigned char)c); });
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

DiskCache::DiskCache(std::string dir, std::uint64_t max_bytes) : dir_(std::move(dir)), max_bytes_(max_bytes) {
  std::error_code ec;
  fs::create_directories(dir_, ec);
  if (!fs::is_directory(dir_, ec)) {
    throw InputError("--disk-cache", dir_ + ": cannot create the directory" + (ec ? " (" + ec.message() + ")" : ""));
  }
  if (::access(dir_.c_str(), W_OK | X_OK) != 0) {
    throw InputError("--disk-cache", dir_ + ": the directory is not writable (" + std::strerror(errno) + ")");
  }
  struct Found {
    std::string name;
    std::uint64_t size;
    fs::file_time_type time;
  };
  std::vector<Found> found;
  for (auto it = fs::directory_iterator(dir_, ec); !ec && it != fs::directory_iterator(); it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.find(kTmp) != std::string::npos && is_entry_name(name.substr(0, 16))) {
      fs::remove(it->path(), ec);  // a write a crash interrupted
      ec.clear();
      continue;
    }
    if (!is_entry_name(name) || !it->is_regular_file(ec)) continue;  // not ours: never touched
    found.push_back({name, std::uint64_t(it->file_size(ec)), it->last_write_time(ec)});
    ec.clear();
  }
  if (ec) throw InputError("--disk-cache", dir_ + ": cannot list the directory (" + ec.message() + ")");
  std::sort(found.begin(), found.end(), [](const Found& a, const Found& b) { return a.time < b.time; });
  std::lock_guard lock(mutex_);
  for (const Found& f : found) insert_locked(f.name, f.size);  // oldest first: the newest ends in front
}

void DiskCache::insert_locked(const std::string& name, std::uint64_t size) {
  erase_locked(name);
  lru_.push_front(name);
  index_[name] = {lru_.begin(), size};
  bytes_ += size;
  while (bytes_ > max_bytes_ && lru_.size() > 1) {
    const std::string victim = lru_.back();
    erase_locked(victim);
    std::error_code ec;
    fs::remove(path(victim), ec);
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
  const auto bad = [&](bool corrupt) -> std::optional<std::vector<std::byte>> {
    (corrupt ? counters_.corrupt : counters_.misses).fetch_add(1, std::memory_order_relaxed);
    if (corrupt) {
      std::lock_guard lock(mutex_);
      erase_locked(name);
      std::error_code ec;
      fs::remove(path(name), ec);
    }
    return std::nullopt;
  };
  std::ifstream f(path(name), std::ios::binary);
  unsigned char h[kHeader];
  if (!f || !f.read(reinterpret_cast<char*>(h), kHeader) || std::memcmp(h, kMagic, 8) != 0) return bad(true);
  const std::uint64_t key_len = get_u64(h + 8), len = get_u64(h + 16);
  std::uint32_t crc = 0;
  for (int i = 3; i >= 0; --i) crc = (crc << 8) | h[24 + i];
  std::error_code ec;
  const std::uint64_t size = fs::file_size(path(name), ec);
  if (ec || size < kHeader || key_len > size - kHeader || len != size - kHeader - key_len) return bad(true);
  std::string stored_key(key_len, '\0');
  std::vector<std::byte> payload(len);
  if (!f.read(stored_key.data(), std::streamsize(key_len)) ||
      !f.read(reinterpret_cast<char*>(payload.data()), std::streamsize(len)) ||
      checksum(stored_key, payload.data(), payload.size()) != crc) {
    return bad(true);
  }
  if (stored_key != key) return bad(false);  // a hash collision: the other key's entry stays
  ::utimensat(AT_FDCWD, path(name).c_str(), nullptr, 0);  // the LRU order a restart rebuilds
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
  bool ok = false;
  {
    std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
    f.write(h.data(), std::streamsize(h.size()));
    f.write(key.data(), std::streamsize(key.size()));
    f.write(reinterpret_cast<const char*>(payload.data()), std::streamsize(payload.size()));
    f.flush();
    ok = bool(f);
  }
  std::error_code ec;
  if (!ok || (fs::rename(tmp, path(name), ec), ec)) {
    fs::remove(tmp, ec);
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
