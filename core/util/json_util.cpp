#include "core/util/json_util.h"

#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>

#include "core/util/error.h"
#include "core/util/input_file.h"

namespace sl {

std::string json_too_large(std::uintmax_t bytes) {
  if (bytes <= kMaxJsonBytes) return {};
  return "is " + std::to_string((bytes + (1u << 20) - 1) >> 20) + " MiB; JSON files are read and parsed whole in memory, at most " +
         std::to_string(kMaxJsonBytes >> 20) + " MiB";
}

bool read_json_bytes(std::istream& in, std::string& out) {
  out.clear();
  char buf[1 << 16];
  while (in.read(buf, sizeof buf) || in.gcount() > 0) {
    out.append(buf, std::size_t(in.gcount()));
    if (out.size() > kMaxJsonBytes) return false;
  }
  return true;
}

std::string read_file_text(const std::string& path) {
  // Opened without blocking and refused unless a regular file (a FIFO would wait for a writer forever;
  // a directory reads as nothing, "malformed JSON").
  const int fd = open_input_fd(path);
  if (fd < 0) throw InputError(path, "cannot open file (no such file)");
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  struct stat st {};
  if (::fstat(fd, &st) == 0) {
    if (const std::string why = json_too_large(std::uintmax_t(st.st_size)); !why.empty()) throw InputError(path, why);
  }
  std::string text;
  char buf[1 << 16];
  for (;;) {
    const ssize_t r = ::read(fd, buf, sizeof buf);
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) throw InputError(path, std::string("read error (") + std::strerror(errno) + ")");
    if (r == 0) break;
    text.append(buf, std::size_t(r));
    if (text.size() > kMaxJsonBytes) {
      throw InputError(path, "holds more than " + std::to_string(kMaxJsonBytes >> 20) +
                                 " MiB; JSON files are read and parsed whole in memory, at most that");
    }
  }
  return text;
}

std::string json_error_text(const nlohmann::json::exception& e) {
  const std::string what = e.what();
  const auto pos = what.find("] ");
  return pos == std::string::npos ? what : what.substr(pos + 2);
}

nlohmann::json parse_json(const std::string& text, const std::string& origin) {
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    // parse_error for syntax, out_of_range.406 for a number that overflows a double (1e999).
    throw InputError(origin, "malformed JSON: " + json_error_text(e));
  }
}

float json_number(const nlohmann::json& j, const char* key, const std::string& origin) {
  if (!j.contains(key)) throw InputError(origin, std::string("missing \"") + key + "\"");
  const auto& v = j[key];
  if (!v.is_number()) throw InputError(origin, std::string("\"") + key + "\" must be a number");
  const double d = v.get<double>();
  // Finite as the float it is kept as: 1e60 is a finite double but an infinite float (which JSON
  // cannot write back; found by the camera_path fuzzer).
  if (!std::isfinite(float(d))) throw InputError(origin, std::string("\"") + key + "\" is not finite as a float");
  return float(d);
}

vec3 json_vec3(const nlohmann::json& j, const char* key, const std::string& origin, bool required) {
  if (!j.contains(key)) {
    if (required) throw InputError(origin, std::string("missing \"") + key + "\"");
    return vec3(0.0f);
  }
  const auto& v = j[key];
  if (!v.is_array() || v.size() != 3) {
    throw InputError(origin, std::string("\"") + key + "\" must be an array of 3 numbers");
  }
  vec3 r;
  for (int i = 0; i < 3; ++i) {
    if (!v[i].is_number()) throw InputError(origin, std::string("\"") + key + "\" must hold numbers");
    const double d = v[i].get<double>();
    if (!std::isfinite(d)) throw InputError(origin, std::string("\"") + key + "\" is not finite");
    r[i] = float(d);
  }
  return r;
}

}  // namespace sl
