// The remote-store tests' HTTP server (tests/data_tools/http_server.py, Debian's /usr/bin/python3,
// standard library only) on 127.0.0.1 at a free port, started by the test and killed by the
// destructor, so no process or fixed port outlives a test. It also exits by itself after ten minutes.
#pragma once

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "tests/test_util.h"

namespace sl::test {

class HttpTestServer {
 public:
  // `args`: further http_server.py flags, space-separated ("--fault-rate 0.2 --faults 500").
  explicit HttpTestServer(const std::filesystem::path& root, const std::string& args = "") {
    const std::filesystem::path dir = root.parent_path();
    static int serial = 0;
    const std::string tag = std::to_string(::getpid()) + "." + std::to_string(serial++);
    port_file_ = (dir / ("http-port." + tag)).string();
    log_file_ = (dir / ("http-log." + tag)).string();
    std::filesystem::remove(port_file_);
    std::vector<std::string> argv = {"/usr/bin/python3", std::string(SL_SOURCE_DIR) + "/tests/data_tools/http_server.py",
                                     "--root", root.string(), "--port-file", port_file_, "--log", log_file_,
                                     "--max-seconds", "600"};
    std::istringstream extra(args);
    for (std::string a; extra >> a;) argv.push_back(a);
    pid_ = ::fork();
    if (pid_ == 0) {
      std::vector<char*> c;
      for (std::string& a : argv) c.push_back(a.data());
      c.push_back(nullptr);
      ::execv(c[0], c.data());
      ::_exit(127);
    }
    if (pid_ < 0) throw std::runtime_error("fork failed");
    for (int i = 0; i < 300; ++i) {  // up to 15 s for the interpreter to start and bind
      std::ifstream f(port_file_);
      if (f >> port_ && port_ > 0) return;
      int status = 0;
      if (::waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = -1;
        throw std::runtime_error("http_server.py exited before listening");
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    stop();
    throw std::runtime_error("http_server.py did not start listening within 15 s");
  }
  ~HttpTestServer() { stop(); }
  HttpTestServer(const HttpTestServer&) = delete;
  HttpTestServer& operator=(const HttpTestServer&) = delete;

  // http://127.0.0.1:PORT/path
  std::string url(const std::string& path = "") const {
    return "http://127.0.0.1:" + std::to_string(port_) + (path.empty() ? "" : "/" + path);
  }
  // Logged requests, one "METHOD PATH RANGE STATUS FAULT" each.
  std::vector<std::string> log() const {
    std::vector<std::string> lines;
    std::ifstream f(log_file_);
    for (std::string l; std::getline(f, l);) lines.push_back(l);
    return lines;
  }
  int port() const { return port_; }

 private:
  void stop() {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGTERM);
    int status = 0;
    ::waitpid(pid_, &status, 0);
    pid_ = -1;
  }
  pid_t pid_ = -1;
  int port_ = 0;
  std::string port_file_, log_file_;
};

}  // namespace sl::test
