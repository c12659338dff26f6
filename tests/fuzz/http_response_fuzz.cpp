// HTTP answers (cache/stores/http_store.cpp: status lines, Content-Length and Content-Range headers,
// chunked and unbounded bodies, through libcurl): an in-process server on 127.0.0.1 answers every
// connection with the input's bytes and closes it. The first input byte picks the read (a whole object
// under a small bound, a byte range, a suffix range); the rest is the raw answer. A read either returns
// what it asked for (a whole object within its bound, a range of exactly its size) or throws InputError.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <thread>

#include "cache/stores/http_store.h"
#include "tests/fuzz/fuzz_util.h"

namespace {

class Server {
 public:
  Server() {
    fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (fd_ < 0 || ::bind(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 || ::listen(fd_, 64) != 0) std::abort();
    socklen_t n = sizeof a;
    ::getsockname(fd_, reinterpret_cast<sockaddr*>(&a), &n);
    port_ = ntohs(a.sin_port);
  }
  int port() const { return port_; }

  // Answers every connection with `answer` until `done` is set.
  void serve(const std::string& answer, const std::atomic<bool>& done) {
    while (!done.load()) {
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, 2) <= 0) continue;
      const int c = ::accept4(fd_, nullptr, nullptr, SOCK_CLOEXEC);
      if (c < 0) continue;
      // The request: up to its blank line (or 64 KiB, or 1 s).
      std::string req;
      char buf[4096];
      for (int i = 0; i < 50 && req.find("\r\n\r\n") == std::string::npos && req.size() < 65536; ++i) {
        pollfd q{c, POLLIN, 0};
        if (::poll(&q, 1, 20) <= 0) continue;
        const ssize_t r = ::recv(c, buf, sizeof buf, 0);
        if (r <= 0) break;
        req.append(buf, std::size_t(r));
      }
      for (std::size_t off = 0; off < answer.size();) {
        const ssize_t w = ::send(c, answer.data() + off, answer.size() - off, MSG_NOSIGNAL);
        if (w <= 0) break;
        off += std::size_t(w);
      }
      ::shutdown(c, SHUT_RDWR);
      ::close(c);
    }
  }

 private:
  int fd_ = -1;
  int port_ = 0;
};

Server& server() {
  static Server s;
  return s;
}

// Redirects would leave the in-process server (curl follows them): the header is renamed.
std::string without_redirects(std::string s) {
  std::string lower = s;
  std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  for (std::size_t i = 0; (i = lower.find("location", i)) != std::string::npos; i += 8) s[i] = 'x';
  return s;
}

}  // namespace

SL_FUZZ_TARGET(input) {
  if (input.empty()) return;
  const unsigned mode = static_cast<unsigned char>(input[0]);
  const std::string answer = without_redirects(std::string(input.substr(1)));
  sl::HttpOptions o;
  o.connect_timeout_ms = 1000;
  o.timeout_ms = 1000;
  o.low_speed_time_s = 1;
  o.tries = 1;
  o.backoff_ms = 0;
  const sl::HttpByteStore store("http://127.0.0.1:" + std::to_string(server().port()) + "/s", o);
  std::atomic<bool> done{false};
  std::thread t([&] { server().serve(answer, done); });
  const std::uint64_t bound = 1 + (mode >> 2) * 37;  // a small bound, so answers can pass it
  const std::uint64_t offset = (mode >> 3) & 7, n = 1 + ((mode >> 5) & 7);
  sl::fuzz::accepted([&] {
    switch (mode & 3) {
      case 0:
      case 3: {
        const auto r = store.read("obj", bound);
        if (r && r->size() > bound) __builtin_trap();
        break;
      }
      case 1: {
        const auto r = store.read_range("obj", offset, n);
        if (r && r->size() != n) __builtin_trap();
        break;
      }
      case 2: {
        const auto r = store.read_suffix("obj", n);
        if (r && r->size() != n) __builtin_trap();
        break;
      }
    }
    return true;
  });
  done = true;
  t.join();
}
