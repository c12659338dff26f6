// Neuroglancer precomputed volumes (cache/formats/precomputed/: info.cpp, source.cpp and the chunk and
// shard decoding behind them): the input is cut at the first NUL byte (which JSON text cannot
// hold) into the `info` file and the bytes every other object of the volume holds (an unsharded chunk,
// or a shard file). The info is parsed and, when it is, the first chunk of every scale read through an
// in-memory ByteStore, so sharding, raw, gzip and compressed_segmentation decoding all see fuzzed bytes.
#include <cstdint>
#include <cstring>
#include <memory>
#include <vector>

#include "cache/formats/precomputed/source.h"
#include "core/util/error.h"
#include "tests/fuzz/fuzz_util.h"

namespace {

// "info" is the first part; every other key holds the second (nullopt when there is none).
class MemoryStore final : public sl::ByteStore {
 public:
  MemoryStore(std::string_view info, std::optional<std::string_view> object) : info_(info), object_(object) {}
  std::optional<std::vector<std::byte>> read(const std::string& key, std::uint64_t) const override {
    if (key == "info") return bytes(info_);
    if (!object_) return std::nullopt;
    return bytes(*object_);
  }
  std::optional<std::vector<std::byte>> read_range(const std::string& key, std::uint64_t offset,
                                                   std::uint64_t n) const override {
    std::optional<std::vector<std::byte>> all = read(key, sl::kMaxChunkObjectBytes);
    if (!all) return std::nullopt;
    if (offset > all->size() || n > all->size() - offset) throw std::runtime_error("byte range past the end");
    return std::vector<std::byte>(all->begin() + std::ptrdiff_t(offset), all->begin() + std::ptrdiff_t(offset + n));
  }
  std::optional<std::vector<std::byte>> read_suffix(const std::string& key, std::uint64_t n) const override {
    std::optional<std::vector<std::byte>> all = read(key, sl::kMaxChunkObjectBytes);
    if (!all) return std::nullopt;
    if (n > all->size()) throw std::runtime_error("suffix past the start");
    return std::vector<std::byte>(all->end() - std::ptrdiff_t(n), all->end());
  }

 private:
  static std::vector<std::byte> bytes(std::string_view s) {
    std::vector<std::byte> b(s.size());
    if (!s.empty()) std::memcpy(b.data(), s.data(), s.size());
    return b;
  }
  std::string_view info_;
  std::optional<std::string_view> object_;
};

}  // namespace

SL_FUZZ_TARGET(input) {
  const auto parts = sl::fuzz::split(input, std::string_view("\0", 1), 2);
  const std::optional<std::string_view> object = parts.size() > 1 ? std::optional(parts[1]) : std::nullopt;
  sl::fuzz::accepted([&] {
    const sl::precomputed::VolumeReader r(std::make_shared<MemoryStore>(parts[0], object), "fuzz",
                                          std::make_shared<sl::zarr::ChunkCache>(0));
    for (int l = 0; l < r.levels(); ++l) {
      const sl::ivec3 n = glm::min(r.info().scales[std::size_t(l)].chunk, r.info().scales[std::size_t(l)].size);
      const std::uint64_t bytes = std::uint64_t(n.x) * std::uint64_t(n.y) * std::uint64_t(n.z) * 4;
      if (bytes > sl::fuzz::kMaxVolumeBytes) continue;
      std::vector<std::byte> box(bytes);
      r.read_box(l, sl::ivec3(0), n, box.data());
    }
    return 0;
  });
}
