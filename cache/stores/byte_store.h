// Where the bytes of a chunked store (Zarr v2/v3, Neuroglancer precomputed) come from. Readers ask only
// for whole objects (chunks, metadata) and byte ranges of objects (a shard's index, one inner chunk of a
// shard), so a local directory (pread) and an HTTP client (Range requests, a suffix range for an index
// at the end) can both serve them.
//
// A store's metadata is untrusted input. Every key passes through store_key() (store_key.h) before a
// file is opened or a request sent; every read carries a bound that the store checks before it
// allocates (a local file's size, an HTTP Content-Length) and while it streams.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace sl {

// Largest metadata object read (zarr.json, .zarray, .zattrs, .zgroup, a precomputed `info`): it is
// parsed whole in memory, and no real one comes near it (core/util/json_util.h's bound for JSON files).
inline constexpr std::uint64_t kMaxMetadataBytes = std::uint64_t(64) << 20;
// Largest index read in one piece (a Zarr v3 shard index, a precomputed minishard index).
inline constexpr std::uint64_t kMaxIndexBytes = std::uint64_t(64) << 20;
// Largest stored chunk read whole: the largest decoded chunk is 1 GiB (zarr/meta.h), and a compressor
// may add a little to incompressible data.
inline constexpr std::uint64_t kMaxChunkObjectBytes = (std::uint64_t(1) << 30) + (std::uint64_t(16) << 20);

class ByteStore {
 public:
  virtual ~ByteStore() = default;
  // The whole object, or nullopt when it does not exist (a chunk never written). Throws
  // std::runtime_error saying why for any other failure, and without reading it all when the object
  // holds more than `max_bytes` (the caller's bound for what it reads: kMaxMetadataBytes, ...).
  virtual std::optional<std::vector<std::byte>> read(const std::string& key, std::uint64_t max_bytes) const = 0;
  // Bytes [offset, offset + n) of the object; nullopt when it does not exist. A range past the end of the
  // object throws std::runtime_error naming the object's size.
  virtual std::optional<std::vector<std::byte>> read_range(const std::string& key, std::uint64_t offset,
                                                           std::uint64_t n) const = 0;
  // The last n bytes of the object (HTTP's suffix range); nullopt when it does not exist; throws when
  // the object is shorter than n.
  virtual std::optional<std::vector<std::byte>> read_suffix(const std::string& key, std::uint64_t n) const = 0;
  // The object's size when the store knows it without a request (a local file's stat), so a reader
  // can refuse a huge metadata object before reading it; nullopt otherwise.
  virtual std::optional<std::uint64_t> size_if_known(const std::string& key) const {
    (void)key;
    return std::nullopt;
  }
};

// Keys are paths relative to `root`; reads are single pread calls, so it is safe from any thread. Only
// regular files are read, opened without blocking (a FIFO or device where an object belongs is refused,
// never waited on), and only when the file opened lies inside the root once symlinks are resolved.
class LocalByteStore final : public ByteStore {
 public:
  explicit LocalByteStore(std::string root);
  std::optional<std::vector<std::byte>> read(const std::string& key, std::uint64_t max_bytes) const override;
  std::optional<std::vector<std::byte>> read_range(const std::string& key, std::uint64_t offset,
                                                   std::uint64_t n) const override;
  std::optional<std::vector<std::byte>> read_suffix(const std::string& key, std::uint64_t n) const override;
  std::optional<std::uint64_t> size_if_known(const std::string& key) const override;
  const std::string& root() const { return root_; }

 private:
  std::string root_;
  std::string canonical_root_;  // realpath of root_; empty when it did not resolve (then resolved per read)
};

}  // namespace sl
