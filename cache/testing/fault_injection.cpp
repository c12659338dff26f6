#include "cache/testing/fault_injection.h"

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <set>
#include <thread>

#include "core/util/config.h"
#include "core/util/error.h"

namespace sl {

namespace {

// splitmix64's finaliser: decisions are independent across (seed, brick, purpose) without any state.
std::uint64_t mix(std::uint64_t seed, std::uint64_t bits, std::uint64_t purpose) {
  std::uint64_t z = seed * 0x9E3779B97F4A7C15ull ^ bits ^ (purpose + 1) * 0xD1B54A32D192ED03ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

double unit(std::uint64_t h) { return double(h >> 11) * 0x1.0p-53; }  // [0, 1)

enum Purpose : std::uint64_t { kKind = 0, kFailingAttempts = 1, kShortLength = 2, kDelay = 3 };

double parse_share(const std::string& option, const std::string& key, const std::string& v) {
  char* end = nullptr;
  const double d = std::strtod(v.c_str(), &end);
  if (v.empty() || end != v.c_str() + v.size() || !std::isfinite(d) || d < 0.0 || d > 1.0) {
    throw InputError(option, key + " must be a share in [0, 1], got '" + v + "'");
  }
  return d;
}

std::uint64_t parse_uint(const std::string& option, const std::string& key, const std::string& v, std::uint64_t lo,
                         std::uint64_t hi) {
  char* end = nullptr;
  errno = 0;
  const unsigned long long n = std::strtoull(v.c_str(), &end, 10);
  if (v.empty() || v[0] == '-' || v[0] == '+' || end != v.c_str() + v.size() || errno == ERANGE || n < lo || n > hi) {
    throw InputError(option, key + " must be an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) +
                                 "], got '" + v + "'");
  }
  return n;
}

}  // namespace

BrickFault FaultSpec::fault(BrickId id) const {
  const double u = unit(mix(seed, id.bits, kKind));
  BrickFault f;
  if (u < permanent) {
    f.kind = FaultKind::Permanent;
  } else if (u < permanent + transient) {
    f.kind = FaultKind::Transient;
  } else if (u < permanent + transient + short_read) {
    f.kind = FaultKind::ShortRead;
  }
  if (f.kind == FaultKind::Transient || f.kind == FaultKind::ShortRead) {
    f.failing_attempts = 1 + int(mix(seed, id.bits, kFailingAttempts) % std::uint64_t(recover));
  }
  return f;
}

bool FaultSpec::delayed(BrickId id, int attempt) const {
  return delay > 0.0 && unit(mix(seed, id.bits, kDelay + std::uint64_t(attempt) * 4)) < delay;
}

FaultSpec parse_fault_spec(const std::string& text, const std::string& option) {
  static const char* kKeys = "permanent, transient, short, recover, delay, delay-ms, seed";
  if (text.empty()) throw InputError(option, std::string("empty fault spec (keys: ") + kKeys + ")");
  FaultSpec s;
  std::set<std::string> seen;
  std::size_t start = 0;
  for (;;) {
    const std::size_t comma = text.find(',', start);
    const std::string item = text.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    const std::size_t eq = item.find('=');
    if (eq == std::string::npos) throw InputError(option, "expected key=value, got '" + item + "'");
    const std::string key = item.substr(0, eq), v = item.substr(eq + 1);
    if (!seen.insert(key).second) throw InputError(option, "'" + key + "' given twice");
    if (key == "permanent") {
      s.permanent = parse_share(option, key, v);
    } else if (key == "transient") {
      s.transient = parse_share(option, key, v);
    } else if (key == "short") {
      s.short_read = parse_share(option, key, v);
    } else if (key == "delay") {
      s.delay = parse_share(option, key, v);
    } else if (key == "recover") {
      s.recover = int(parse_uint(option, key, v, 1, 1000));
    } else if (key == "delay-ms") {
      s.delay_ms = int(parse_uint(option, key, v, 0, 60000));
    } else if (key == "seed") {
      s.seed = parse_uint(option, key, v, 0, UINT64_MAX);
    } else {
      throw InputError(option, "unknown key '" + key + "' (expected " + kKeys + ")");
    }
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  if (s.fault_share() > 1.0 + 1e-12) {
    throw InputError(option, "permanent + transient + short must not exceed 1 (a brick has at most one fault)");
  }
  return s;
}

FaultInjectingSource::FaultInjectingSource(std::shared_ptr<const VolumeSource> inner, const FaultSpec& spec)
    : inner_(std::move(inner)), spec_(spec) {
  SL_CHECK(inner_ != nullptr && spec_.recover >= 1 && spec_.fault_share() <= 1.0 + 1e-12 && spec_.delay_ms >= 0);
}

int FaultInjectingSource::attempts(BrickId id) const {
  std::lock_guard lock(mutex_);
  const auto it = attempts_.find(id);
  return it == attempts_.end() ? 0 : it->second;
}

template <class Read>
void FaultInjectingSource::faulty_read(BrickId id, std::span<std::byte> out_intensity, std::span<std::byte> out_labels,
                                       Read&& read) const {
  int attempt = 0;
  {
    std::lock_guard lock(mutex_);
    attempt = attempts_[id]++;
  }
  if (spec_.delayed(id, attempt)) std::this_thread::sleep_for(std::chrono::milliseconds(spec_.delay_ms));
  const BrickFault f = spec_.fault(id);
  // Each message names the brick: an injected fault covers exactly one brick (no shared chunk), and
  // the renderer reports one warning per distinct cause.
  const std::string where = " in " + to_string(id);
  if (f.kind == FaultKind::Permanent) throw InputError(name(), "injected read error" + where);
  const bool fails = attempt < f.failing_attempts;
  if (f.kind == FaultKind::Transient && fails) {
    throw TransientError(name(), "injected transient error" + where + " (attempt " + std::to_string(attempt + 1) +
                                     " of " + std::to_string(f.failing_attempts) + " failing)");
  }
  read();
  if (f.kind == FaultKind::ShortRead && fails) {
    // Part of the brick arrived; the rest of the buffer is garbage, as after an interrupted transfer.
    const std::size_t total = out_intensity.size() + out_labels.size();
    const std::size_t got = std::size_t(mix(spec_.seed, id.bits, kShortLength + 4 * std::uint64_t(attempt)) % total);
    const std::size_t in_intensity = std::min(got, out_intensity.size());
    if (in_intensity < out_intensity.size()) {
      std::memset(out_intensity.data() + in_intensity, 0xA5, out_intensity.size() - in_intensity);
    }
    const std::size_t in_labels = got - in_intensity;
    if (in_labels < out_labels.size()) std::memset(out_labels.data() + in_labels, 0xA5, out_labels.size() - in_labels);
    throw TransientError(name(), "short read: " + std::to_string(got) + " of " + std::to_string(total) +
                                     " bytes (injected" + where + ")");
  }
}

void FaultInjectingSource::read_brick(const BrickLayout& layout, BrickId id, std::span<std::byte> out_intensity,
                                      std::span<std::byte> out_labels) const {
  faulty_read(id, out_intensity, out_labels, [&] { inner_->read_brick(layout, id, out_intensity, out_labels); });
}

void FaultInjectingSource::read_brick_bounded(const BrickLayout& layout, BrickId id, std::span<std::byte> out_intensity,
                                              std::span<std::byte> out_labels, int block,
                                              std::vector<BlockMetadata>& bounds) const {
  faulty_read(id, out_intensity, out_labels,
              [&] { inner_->read_brick_bounded(layout, id, out_intensity, out_labels, block, bounds); });
}

}  // namespace sl
