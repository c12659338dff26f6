// Where a chunked store lives, from how the user names it: a local directory, an http:// or
// https:// URL, or one of those behind a format prefix as Neuroglancer writes it: `zarr://`,
// `zarr2://`, `zarr3://` (the Zarr version is still read from the store) and `precomputed://`. Without
// a prefix the kind is recognised by what the store holds: zarr.json (Zarr v3), .zattrs/.zarray/.zgroup
// (Zarr v2) or a precomputed `info`.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "cache/stores/byte_store.h"
#include "cache/stores/store_kind.h"

namespace sl {

class DiskCache;

// True when `spec` starts with "scheme://" (any scheme: unsupported ones are refused by open_url_store).
bool is_url(const std::string& spec);

struct UrlStore {
  std::shared_ptr<const ByteStore> bytes;  // through the disk cache when one is set (remote only)
  StoreKind kind = StoreKind::None;        // from the prefix; None when none was given
  std::string location;                    // the URL or directory without the prefix
};

// The store a URL names. Throws InputError(spec, why) for an unsupported scheme, a URL without a host,
// a prefixed local directory that does not exist.
UrlStore open_url_store(const std::string& spec);

// The bytes of the store at `path`: open_url_store(path).bytes for a URL, a LocalByteStore otherwise
// (the directory is not checked here: its reader names a missing one).
std::shared_ptr<const ByteStore> open_byte_store(const std::string& path);

// What the store holds, probing zarr.json, .zattrs, .zarray, .zgroup, then info (a network request
// each for a URL); None when none exists.
StoreKind probe_store_kind(const ByteStore& bytes);

// recognise_store (store_kind.h) for a URL: the prefix's kind; else Zarr for a name ending in .zarr;
// else what probe_store_kind finds, Zarr when it finds nothing (the Zarr reader then names what is
// missing). `path` is the spec without its kind prefix. Remembered for the process, so repeated
// questions cost no requests. A failing probe throws (one line naming the URL and the failure).
StoreLocation recognise_url(const std::string& spec);

// "remote: N requests on K connections, X MB, R retried, F failed after retries, W whole answers to
// ranges; disk cache H hits, M misses, C corrupt, E evicted, B MB in F files" for what the process read
// over HTTP (empty when it made no request and has no disk cache).
std::string remote_summary();

// The on-disk cache every remote store opened afterwards reads through (null: none).
void set_disk_cache(std::shared_ptr<DiskCache> cache);
std::shared_ptr<DiskCache> disk_cache();

}  // namespace sl
