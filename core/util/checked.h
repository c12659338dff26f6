// Size arithmetic on numbers read from files and stores (shapes, chunk and shard sizes, index sizes,
// bit counts). Such numbers are untrusted input: a product or a rounding-up division that wraps around
// 64 bits turns into a small size (a grid of 0 shards, a short buffer) and then into a wrong image or a
// crash. Every such computation goes through these helpers, which refuse a wrap with a message naming
// the quantity and its operands; readers add the file (InputError) when they catch it.
#pragma once

#include <cstdint>
#include <initializer_list>
#include <span>
#include <stdexcept>
#include <string>

namespace sl {

// What the helpers throw: a std::runtime_error, so readers that wrap metadata errors with the file name
// wrap this one too.
class SizeOverflow : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

namespace checked_detail {
inline std::string operands(std::span<const std::uint64_t> v, const char* op) {
  std::string t;
  for (std::size_t i = 0; i < v.size(); ++i) t += (i ? op : "") + std::to_string(v[i]);
  return t;
}
}  // namespace checked_detail

// a * b; throws SizeOverflow("<what> (a x b) overflows 64-bit arithmetic").
inline std::uint64_t checked_mul(std::uint64_t a, std::uint64_t b, const std::string& what) {
  std::uint64_t r = 0;
  if (__builtin_mul_overflow(a, b, &r)) {
    const std::uint64_t v[2] = {a, b};
    throw SizeOverflow(what + " (" + checked_detail::operands(v, " x ") + ") overflows 64-bit arithmetic");
  }
  return r;
}

// a + b; throws SizeOverflow naming `what`.
inline std::uint64_t checked_add(std::uint64_t a, std::uint64_t b, const std::string& what) {
  std::uint64_t r = 0;
  if (__builtin_add_overflow(a, b, &r)) {
    const std::uint64_t v[2] = {a, b};
    throw SizeOverflow(what + " (" + checked_detail::operands(v, " + ") + ") overflows 64-bit arithmetic");
  }
  return r;
}

// ceil(a / b) without forming a + b - 1 (which wraps for a near 2^64); b == 0 throws.
inline std::uint64_t checked_ceil_div(std::uint64_t a, std::uint64_t b, const std::string& what) {
  if (b == 0) throw SizeOverflow(what + ": division by zero (" + std::to_string(a) + " / 0)");
  return a / b + (a % b != 0 ? 1 : 0);
}

// v << bits (v * 2^bits); throws when bits >= 64 or the result loses bits.
inline std::uint64_t checked_shl(std::uint64_t v, int bits, const std::string& what) {
  if (bits < 0 || bits >= 64 || (v != 0 && (v >> (63 - bits)) > 1)) {
    throw SizeOverflow(what + " (" + std::to_string(v) + " x 2^" + std::to_string(bits) + ") overflows 64-bit arithmetic");
  }
  return v << bits;
}

// The product of `v` (negative entries are refused: they are never sizes); throws naming every operand.
template <class Int>
inline std::uint64_t checked_product(std::span<const Int> v, const std::string& what, std::uint64_t init = 1) {
  std::uint64_t r = init;
  bool wrapped = false;
  for (const Int x : v) {
    if (x < 0) throw SizeOverflow(what + ": negative size " + std::to_string(x));
    wrapped = wrapped || __builtin_mul_overflow(r, std::uint64_t(x), &r);
  }
  if (wrapped) {
    std::string t = init == 1 ? std::string() : std::to_string(init) + " x ";
    for (std::size_t i = 0; i < v.size(); ++i) t += (i ? " x " : "") + std::to_string(v[i]);
    throw SizeOverflow(what + " (" + t + ") overflows 64-bit arithmetic");
  }
  return r;
}
template <class Int>
inline std::uint64_t checked_product(std::initializer_list<Int> v, const std::string& what, std::uint64_t init = 1) {
  return checked_product(std::span<const Int>(v.begin(), v.size()), what, init);
}

// "N bytes (M MiB)" for messages about sizes.
inline std::string bytes_text(std::uint64_t n) {
  if (n < (std::uint64_t(1) << 20)) return std::to_string(n) + " bytes";
  return std::to_string(n) + " bytes (" + std::to_string((n + (std::uint64_t(1) << 20) - 1) >> 20) + " MiB)";
}

// `n` unless it exceeds `max`: then SizeOverflow("<what> of N bytes exceeds the M bound"), before
// anything of that size is allocated or read.
inline std::uint64_t checked_bound(std::uint64_t n, std::uint64_t max, const std::string& what) {
  if (n > max) throw SizeOverflow(what + " of " + bytes_text(n) + " exceeds the " + bytes_text(max) + " bound");
  return n;
}

}  // namespace sl
