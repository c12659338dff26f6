// Sets of enabled segmentation labels (paper §5.2 "segmented objects"), the --enable syntax, and a
// stable colour per label id for label rendering.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "core/util/config.h"
#include "core/util/math.h"

namespace sl {

// Plain view of a LabelSet: bit `id` of the word array. Copyable to a device.
struct LabelSetView {
  const std::uint32_t* bits = nullptr;
  std::uint32_t size = 0;  // number of representable ids (0 .. size-1)

  SL_HOST_DEVICE bool enabled(std::uint32_t id) const {
    return id < size && ((bits[id >> 5] >> (id & 31u)) & 1u) != 0u;
  }
};

// Largest label id a label table holds: a dense bitset of 8 MiB, filled in ~0.1 s. Larger ids (a label
// volume with one stray 0xFFFFFFFE voxel) would cost 512 MiB and seconds per table, so they are refused.
inline constexpr std::uint32_t kMaxLabelId = (1u << 26) - 1u;
// Throws InputError(origin, reason naming the table size) when max_id > kMaxLabelId.
void check_label_table(std::uint32_t max_id, const std::string& origin);

// Dense bitset over label ids. Label 0 is the background and is never enabled.
class LabelSet {
 public:
  LabelSet() = default;
  explicit LabelSet(std::uint32_t size) { resize(size); }
  // Labels 1..label_count enabled; label_count <= kMaxLabelId.
  static LabelSet all(std::uint32_t label_count);

  void enable(std::uint32_t id);  // grows the set; enable(0) is ignored (background)
  void disable(std::uint32_t id);
  bool enabled(std::uint32_t id) const { return view().enabled(id); }
  std::uint32_t count() const { return count_; }  // number of enabled ids
  std::uint32_t size() const { return size_; }    // representable ids: 0 .. size-1
  // True when any id of `ids` is enabled.
  bool any_enabled(std::span<const std::uint32_t> ids) const;
  std::vector<std::uint32_t> ids() const;  // enabled ids, ascending

  LabelSetView view() const { return LabelSetView{words_.data(), size_}; }
  const std::vector<std::uint32_t>& words() const { return words_; }

 private:
  void resize(std::uint32_t size);

  std::vector<std::uint32_t> words_;
  std::uint32_t size_ = 0;
  std::uint32_t count_ = 0;
};

// Parses the --enable syntax over labels 1..label_count:
//   "all" | "none" | a list of ids and inclusive ranges "1,5,10-20" |
//   "fraction:P:SEED" (exactly round(P * label_count) ids, a deterministic pseudo-random subset).
// Throws InputError("--enable", reason) on a malformed spec, id 0, or an id above label_count.
LabelSet parse_enable_spec(const std::string& spec, std::uint32_t label_count);

// A stable, well-spread colour per label id (hash -> hue, varied saturation/value); id 0 is black.
SL_HOST_DEVICE inline vec3 label_color(std::uint32_t id) {
  if (id == 0u) return vec3(0.0f);
  std::uint32_t h = id * 0x9E3779B9u;  // murmur3 finaliser over a golden-ratio spread of the id
  h ^= h >> 16;
  h *= 0x85EBCA6Bu;
  h ^= h >> 13;
  h *= 0xC2B2AE35u;
  h ^= h >> 16;
  const float hue = float(h & 0xFFFFu) * (6.0f / 65536.0f);  // [0, 6)
  const float sat = 0.55f + 0.40f * float((h >> 16) & 0xFFu) / 255.0f;
  const float val = 0.75f + 0.25f * float((h >> 24) & 0xFFu) / 255.0f;
  const int sector = int(hue);
  const float f = hue - float(sector);
  const float p = val * (1.0f - sat);
  const float q = val * (1.0f - sat * f);
  const float u = val * (1.0f - sat * (1.0f - f));
  switch (sector) {
    case 0: return vec3(val, u, p);
    case 1: return vec3(q, val, p);
    case 2: return vec3(p, val, u);
    case 3: return vec3(p, q, val);
    case 4: return vec3(u, p, val);
    default: return vec3(val, p, q);
  }
}

}  // namespace sl
