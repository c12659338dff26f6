#include "cache/stores/store_key.h"

#include <unistd.h>

#include <climits>
#include <cstdio>
#include <stdexcept>
#include <vector>

namespace sl {
namespace {

int hex_digit(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

[[noreturn]] void refuse(std::string_view key, const std::string& why) {
  throw std::runtime_error("key '" + printable_key(key) + "' " + why);
}

// The segments of one decoding stage, checked; `key` is the original (for messages).
void check_stage(std::string_view key, std::string_view s) {
  if (s.empty()) return;
  if (s.front() == '/') refuse(key, "is an absolute path (keys are relative to the store)");
  for (const char c : s) {
    const unsigned char u = static_cast<unsigned char>(c);
    if (u < 0x20 || u == 0x7f) refuse(key, "holds a control byte");
    if (c == '\\') refuse(key, "holds a backslash (some servers read it as '/')");
    if (c == '?' || c == '#') refuse(key, std::string("holds a '") + c + "' (it would end the URL's path)");
  }
  std::size_t a = 0;
  while (a <= s.size()) {
    std::size_t b = s.find('/', a);
    if (b == std::string_view::npos) b = s.size();
    const std::string_view seg = s.substr(a, b - a);
    if (seg == "..") refuse(key, "has a '..' segment (keys must stay inside the store)");
    if (seg.empty() && b < s.size()) refuse(key, "has an empty segment ('//')");
    a = b + 1;
  }
}

// One percent-decoding of `s`; false when nothing was escaped. A '%' that does not start a valid escape
// is refused: servers differ on what it means.
bool percent_decode(std::string_view key, const std::string& s, std::string& out) {
  out.clear();
  bool any = false;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s[i] != '%') {
      out += s[i];
      continue;
    }
    const int h = i + 1 < s.size() ? hex_digit(s[i + 1]) : -1;
    const int l = i + 2 < s.size() ? hex_digit(s[i + 2]) : -1;
    if (h < 0 || l < 0) refuse(key, "has a '%' that is not a percent-escape");
    out += char(h * 16 + l);
    i += 2;
    any = true;
  }
  return any;
}

}  // namespace

std::string printable_key(std::string_view key) {
  std::string t;
  for (const char c : key.substr(0, 200)) {
    const unsigned char u = static_cast<unsigned char>(c);
    if (u < 0x20 || u == 0x7f) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02x", u);
      t += buf;
    } else {
      t += c;
    }
  }
  if (key.size() > 200) t += "...";
  return t;
}

std::string store_key(std::string_view key) {
  // Every stage a server could see: the key as written and each percent-decoding of it, until no
  // escape is left (bounded: each decoding shortens the text).
  std::string stage(key), next;
  check_stage(key, stage);
  while (percent_decode(key, stage, next)) {
    stage.swap(next);
    check_stage(key, stage);
  }
  // Normal form of the key as written: "." segments dropped, a trailing '/' dropped.
  std::string out;
  std::size_t a = 0;
  while (a <= key.size()) {
    std::size_t b = key.find('/', a);
    if (b == std::string_view::npos) b = key.size();
    const std::string_view seg = key.substr(a, b - a);
    if (!seg.empty() && seg != ".") {
      if (!out.empty()) out += '/';
      out += seg;
    }
    a = b + 1;
  }
  return out;
}

std::string local_store_path(const std::string& root, std::string_view key) {
  const std::string k = store_key(key);
  return k.empty() ? root : root + "/" + k;
}

std::string store_url(const std::string& base, std::string_view key) {
  const std::string k = store_key(key);
  return k.empty() ? base : base + "/" + k;
}

bool fd_inside(int fd, const std::string& canonical_root, std::string* where) {
  char link[64];
  std::snprintf(link, sizeof link, "/proc/self/fd/%d", fd);
  std::vector<char> buf(PATH_MAX + 1);
  const ssize_t n = ::readlink(link, buf.data(), buf.size() - 1);
  if (n < 0) return true;  // no /proc: the lexical check of store_key stands alone
  const std::string p(buf.data(), std::size_t(n));
  if (where) *where = p;
  if (canonical_root == "/") return true;
  return p == canonical_root || (p.size() > canonical_root.size() && p.compare(0, canonical_root.size(), canonical_root) == 0 &&
                                 p[canonical_root.size()] == '/');
}

}  // namespace sl
