#include "core/scene/labels.h"

#include <algorithm>
#include <charconv>
#include <cmath>

#include "core/util/error.h"
#include "core/util/rng.h"

namespace sl {

void LabelSet::resize(std::uint32_t size) {
  if (size <= size_) return;
  words_.resize((std::size_t(size) + 31u) / 32u, 0u);
  size_ = size;
}

LabelSet LabelSet::all(std::uint32_t label_count) {
  SL_CHECK(label_count <= kMaxLabelId);
  LabelSet s(label_count + 1u);
  // 64-bit counter: a 32-bit one wraps at id 0xFFFFFFFF and never ends.
  for (std::uint64_t i = 1; i <= label_count; ++i) s.enable(std::uint32_t(i));
  return s;
}

void LabelSet::enable(std::uint32_t id) {
  if (id == 0u) return;  // background is never enabled
  if (id >= size_) resize(id + 1u);
  std::uint32_t& w = words_[id >> 5];
  const std::uint32_t bit = 1u << (id & 31u);
  if (!(w & bit)) {
    w |= bit;
    ++count_;
  }
}

void LabelSet::disable(std::uint32_t id) {
  if (id >= size_) return;
  std::uint32_t& w = words_[id >> 5];
  const std::uint32_t bit = 1u << (id & 31u);
  if (w & bit) {
    w &= ~bit;
    --count_;
  }
}

bool LabelSet::any_enabled(std::span<const std::uint32_t> ids) const {
  const LabelSetView v = view();
  for (std::uint32_t id : ids) {
    if (v.enabled(id)) return true;
  }
  return false;
}

std::vector<std::uint32_t> LabelSet::ids() const {
  std::vector<std::uint32_t> out;
  out.reserve(count_);
  for (std::uint32_t i = 0; i < size_; ++i) {
    if (enabled(i)) out.push_back(i);
  }
  return out;
}

void check_label_table(std::uint32_t max_id, const std::string& origin) {
  if (max_id <= kMaxLabelId) return;
  const std::uint64_t mib = ((std::uint64_t(max_id) + 32u) / 32u * 4u + (1u << 20) - 1u) >> 20;
  throw InputError(origin, "largest label id " + std::to_string(max_id) + " would need a " + std::to_string(mib) +
                               " MiB label table; ids must be at most " + std::to_string(kMaxLabelId));
}

namespace {

[[noreturn]] void bad(const std::string& reason) { throw InputError("--enable", reason); }

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t");
  if (b == std::string::npos) return {};
  const auto e = s.find_last_not_of(" \t");
  return s.substr(b, e - b + 1);
}

template <class T>
T parse_number(const std::string& text, const std::string& what, const std::string& spec) {
  const std::string s = trim(text);
  T v{};
  const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (s.empty() || ec != std::errc() || p != s.data() + s.size()) {
    bad("'" + s + "' is not " + what + " in '" + spec + "'");
  }
  return v;
}

// fraction:P[:SEED]: exactly round(P * label_count) ids, those with the smallest hash(seed, id), so
// the subset is deterministic on every platform and grows monotonically with P for a fixed seed.
LabelSet parse_fraction(const std::string& spec, std::uint32_t label_count) {
  const std::string rest = spec.substr(9);
  const auto colon = rest.find(':');
  const double p = parse_number<double>(rest.substr(0, colon), "a fraction", spec);
  const std::uint64_t seed =
      colon == std::string::npos ? 1u : parse_number<std::uint64_t>(rest.substr(colon + 1), "a seed", spec);
  if (!(p >= 0.0 && p <= 1.0)) bad("fraction must be in [0, 1] in '" + spec + "'");
  const std::uint32_t k = std::uint32_t(std::llround(p * double(label_count)));
  std::vector<std::pair<std::uint64_t, std::uint32_t>> keyed(label_count);
  for (std::uint32_t i = 0; i < label_count; ++i) {
    keyed[i] = {splitmix64(splitmix64(seed) ^ (i + 1u)), i + 1u};
  }
  std::nth_element(keyed.begin(), keyed.begin() + k, keyed.end());
  LabelSet set(label_count + 1u);
  for (std::uint32_t i = 0; i < k; ++i) set.enable(keyed[i].second);
  return set;
}

}  // namespace

LabelSet parse_enable_spec(const std::string& raw, std::uint32_t label_count) {
  const std::string spec = trim(raw);
  if (spec.empty()) bad("empty label spec (expected all, none, a list like 1,5,10-20, or fraction:P:SEED)");
  if (spec == "all") return LabelSet::all(label_count);
  if (spec == "none") return LabelSet(label_count + 1u);
  if (spec.rfind("fraction:", 0) == 0) return parse_fraction(spec, label_count);

  LabelSet set(label_count + 1u);
  std::size_t pos = 0;
  while (pos <= spec.size()) {
    const auto comma = spec.find(',', pos);
    const std::string item = trim(spec.substr(pos, comma == std::string::npos ? std::string::npos : comma - pos));
    if (item.empty()) bad("empty item in '" + spec + "'");
    const auto dash = item.find('-', 1);
    std::uint32_t lo, hi;
    if (dash == std::string::npos) {
      lo = hi = parse_number<std::uint32_t>(item, "a label id", spec);
    } else {
      lo = parse_number<std::uint32_t>(item.substr(0, dash), "a label id", spec);
      hi = parse_number<std::uint32_t>(item.substr(dash + 1), "a label id", spec);
      if (hi < lo) bad("empty range '" + item + "' in '" + spec + "'");
    }
    if (lo == 0u) bad("label 0 is the background and cannot be enabled ('" + spec + "')");
    if (hi > label_count) {
      bad("label " + std::to_string(hi) + " exceeds the largest label " + std::to_string(label_count));
    }
    for (std::uint64_t i = lo; i <= hi; ++i) set.enable(std::uint32_t(i));
    if (comma == std::string::npos) break;
    pos = comma + 1;
  }
  return set;
}

}  // namespace sl
