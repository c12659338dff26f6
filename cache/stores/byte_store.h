// Where the bytes of a chunked store (Zarr v2/v3, Neuroglancer precomputed) come from. Readers ask only
// for whole objects (chunks, metadata) and byte ranges of objects (a shard's index, one inner chunk of a
// shard), so a local directory (pread) and an HTTP client (Range requests, a suffix range for an index
// at the end) can both serve them.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace sl {

class ByteStore {
 public:
  virtual ~ByteStore() = default;
  // The whole object, or nullopt when it does not exist (a chunk never written). Throws
  // std::runtime_error saying why for any other failure.
  virtual std::optional<std::vector<std::byte>> read(const std::string& key) const = 0;
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

// Keys are paths relative to `root`; reads are single pread calls, so it is safe from any thread.
class LocalByteStore final : public ByteStore {
 public:
  explicit LocalByteStore(std::string root) : root_(std::move(root)) {}
  std::optional<std::vector<std::byte>> read(const std::string& key) const override;
  std::optional<std::vector<std::byte>> read_range(const std::string& key, std::uint64_t offset,
                                                   std::uint64_t n) const override;
  std::optional<std::vector<std::byte>> read_suffix(const std::string& key, std::uint64_t n) const override;
  std::optional<std::uint64_t> size_if_known(const std::string& key) const override;
  const std::string& root() const { return root_; }

 private:
  std::string root_;
};

}  // namespace sl
