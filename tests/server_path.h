// What a web server makes of a URL path, as the store-key tests' oracle: percent-decoded as often as a
// chain of proxies and servers might decode it, backslashes read as '/', dot segments removed (RFC 3986
// remove_dot_segments). A path that climbs above the root is "<above the root>", which lies inside no
// store. Shared by tests/cache/stores/store_key_test.cpp and the store_key fuzzer.
#pragma once

#include <cctype>
#include <string>
#include <vector>

namespace sl::test {

inline std::string server_path(std::string p) {
  const auto hex = [](char c) { return std::isxdigit(static_cast<unsigned char>(c)) != 0; };
  for (int round = 0; round < 8; ++round) {
    std::string d;
    for (std::size_t i = 0; i < p.size(); ++i) {
      if (p[i] == '%' && i + 2 < p.size() && hex(p[i + 1]) && hex(p[i + 2])) {
        d += char(std::stoi(p.substr(i + 1, 2), nullptr, 16));
        i += 2;
      } else {
        d += p[i];
      }
    }
    p = d;
  }
  for (char& c : p) c = c == '\\' ? '/' : c;
  std::vector<std::string> out;
  std::size_t a = 0;
  while (a <= p.size()) {
    std::size_t b = p.find('/', a);
    if (b == std::string::npos) b = p.size();
    const std::string seg = p.substr(a, b - a);
    if (seg == "..") {
      if (out.empty()) return "<above the root>";
      out.pop_back();
    } else if (!seg.empty() && seg != ".") {
      out.push_back(seg);
    }
    a = b + 1;
  }
  std::string r;
  for (const std::string& s : out) r += "/" + s;
  return r;
}

}  // namespace sl::test
