// A message as printed on one line of stderr (the error line of apps/main.cpp, the out-of-core
// warnings): control bytes, which a corrupt header, chunk or file name can carry into the reason, are
// escaped as \xNN, so the message stays one line and cannot drive the terminal.
#pragma once

#include <cstdio>
#include <string>
#include <string_view>

namespace sl {

inline std::string printable(std::string_view s) {
  std::string out;
  for (const char c : s) {
    const auto u = static_cast<unsigned char>(c);
    if (u < 0x20 || u == 0x7f) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02x", u);
      out += buf;
    } else {
      out += c;
    }
  }
  return out;
}

}  // namespace sl
