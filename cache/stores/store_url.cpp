#include "cache/stores/store_url.h"

#include <cctype>
#include <cstdio>
#include <filesystem>
#include <map>
#include <mutex>

#include "cache/stores/disk_cache.h"
#include "cache/stores/http_store.h"
#include "core/util/error.h"

namespace sl {
namespace {

std::mutex g_mutex;
std::shared_ptr<DiskCache> g_disk_cache;
std::map<std::string, StoreLocation> g_recognised;  // recognise_url's answers

bool starts_with(const std::string& s, const char* p) { return s.rfind(p, 0) == 0; }

}  // namespace

bool is_url(const std::string& spec) {
  const std::size_t p = spec.find("://");
  if (p == std::string::npos || p == 0) return false;
  for (std::size_t i = 0; i < p; ++i) {
    const char c = spec[i];
    if (!(std::isalnum((unsigned char)c) || c == '+' || c == '-' || c == '.')) return false;
  }
  return std::isalpha((unsigned char)spec[0]) != 0;
}

UrlStore open_url_store(const std::string& spec) {
  UrlStore u;
  const StoreLocation prefixed = split_kind_prefix(spec);
  u.kind = prefixed.kind;
  u.location = prefixed.path;
  const bool http = starts_with(u.location, "http://"), https = starts_with(u.location, "https://");
  if (!http && !https) {
    if (is_url(u.location)) {
      throw InputError(spec, "unsupported URL scheme '" + u.location.substr(0, u.location.find("://")) +
                                 "' (expected http://, https://, or zarr://, zarr2://, zarr3://, precomputed:// "
                                 "before a URL or directory)");
    }
    if (u.kind == StoreKind::None) throw InputError(spec, "not a URL");
    std::error_code ec;
    if (!std::filesystem::is_directory(u.location, ec)) throw InputError(spec, "no such store (directory)");
    u.bytes = std::make_shared<LocalByteStore>(u.location);
    return u;
  }
  const std::string rest = u.location.substr(http ? 7 : 8);
  const std::string host = rest.substr(0, rest.find_first_of("/?#"));
  if (host.empty()) throw InputError(spec, "the URL has no host");
  if (rest.find_first_of("?#") != std::string::npos) {
    throw InputError(spec, "a store URL takes no query or fragment (object keys are appended to its path)");
  }
  std::shared_ptr<const ByteStore> bytes = std::make_shared<HttpByteStore>(u.location);
  if (std::shared_ptr<DiskCache> c = disk_cache()) {
    std::string name = u.location;
    while (!name.empty() && name.back() == '/') name.pop_back();
    bytes = std::make_shared<CachedByteStore>(std::move(bytes), name, std::move(c));
  }
  u.bytes = std::move(bytes);
  return u;
}

std::shared_ptr<const ByteStore> open_byte_store(const std::string& path) {
  if (is_url(path)) return open_url_store(path).bytes;
  return std::make_shared<LocalByteStore>(path);
}

StoreKind probe_store_kind(const ByteStore& bytes) {
  for (const char* k : {"zarr.json", ".zattrs", ".zarray", ".zgroup"}) {
    if (bytes.read(k, kMaxMetadataBytes)) return StoreKind::Zarr;
  }
  return bytes.read("info", kMaxMetadataBytes) ? StoreKind::Precomputed : StoreKind::None;
}

StoreLocation recognise_url(const std::string& spec) {
  {
    std::lock_guard lock(g_mutex);
    if (const auto it = g_recognised.find(spec); it != g_recognised.end()) return it->second;
  }
  const UrlStore u = open_url_store(spec);
  StoreLocation r{u.kind, u.location};
  if (r.kind == StoreKind::None) {
    try {
      r.kind = named_zarr(u.location) ? StoreKind::Zarr : probe_store_kind(*u.bytes);
    } catch (const std::runtime_error& e) {
      throw InputError(spec, std::string("cannot probe the store (") + e.what() + ")");
    }
    // Nothing found: opened as Zarr, whose reader names what is missing.
    if (r.kind == StoreKind::None) r.kind = StoreKind::Zarr;
  }
  std::lock_guard lock(g_mutex);
  g_recognised[spec] = r;
  return r;
}

std::string remote_summary() {
  const HttpCounters& h = http_counters();
  const std::shared_ptr<DiskCache> c = disk_cache();
  if (h.requests == 0 && !c) return {};
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "remote: %llu requests on %llu connections, %.2f MB, %llu retried, %llu failed after retries, %llu whole "
                "answers to ranges",
                (unsigned long long)h.requests, (unsigned long long)h.connections, double(h.bytes) / 1e6, (unsigned long long)h.retries,
                (unsigned long long)h.failed, (unsigned long long)h.whole_for_range);
  std::string s = buf;
  if (c) {
    const DiskCacheCounters& d = c->counters();
    std::snprintf(buf, sizeof buf, "; disk cache %llu hits, %llu misses, %llu corrupt, %llu evicted, %.2f MB in %zu files",
                  (unsigned long long)d.hits, (unsigned long long)d.misses, (unsigned long long)d.corrupt,
                  (unsigned long long)d.evicted, double(c->bytes()) / 1e6, c->files());
    s += buf;
  }
  return s;
}

void set_disk_cache(std::shared_ptr<DiskCache> cache) {
  std::lock_guard lock(g_mutex);
  g_disk_cache = std::move(cache);
}

std::shared_ptr<DiskCache> disk_cache() {
  std::lock_guard lock(g_mutex);
  return g_disk_cache;
}

}  // namespace sl
