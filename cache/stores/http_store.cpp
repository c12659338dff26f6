#include "cache/stores/http_store.h"

#include <curl/curl.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <thread>
#include <vector>

#include "cache/stores/store_key.h"
#include "core/util/checked.h"
#include "core/util/config.h"
#include "core/util/error.h"

namespace sl {
namespace {

// The body of an answer to a range request is bounded too (a server that ignores Range sends the whole
// object, which is sliced): a shard is at most this big; a server that streams without end must not
// take all memory. Whole-object reads carry their caller's bound (byte_store.h).
constexpr std::uint64_t kMaxBodyBytes = std::uint64_t(4) << 30;

// The share object behind every HttpByteStore: connections, DNS and TLS sessions are reused through
// it. Easy handles are not: each request gets a fresh one, since an easy handle keeps per-request
// state across curl_easy_reset (libcurl 7.88 keeps the last header of the previous answer, and an
// answer that opens with a folded header line then writes through that stale pointer: a hostile
// server could corrupt memory; found by the http_response fuzzer). It lives for the whole process
// (never destroyed), since loader threads may still hold a handle while statics are torn down.
class Client {
 public:
  Client() {
    curl_global_init(CURL_GLOBAL_DEFAULT);
    share_ = curl_share_init();
    curl_share_setopt(share_, CURLSHOPT_LOCKFUNC, &Client::lock);
    curl_share_setopt(share_, CURLSHOPT_UNLOCKFUNC, &Client::unlock);
    curl_share_setopt(share_, CURLSHOPT_USERDATA, this);
    curl_share_setopt(share_, CURLSHOPT_SHARE, CURL_LOCK_DATA_CONNECT);
    curl_share_setopt(share_, CURLSHOPT_SHARE, CURL_LOCK_DATA_DNS);
    curl_share_setopt(share_, CURLSHOPT_SHARE, CURL_LOCK_DATA_SSL_SESSION);
  }
  CURL* acquire() {
    CURL* h = curl_easy_init();
    if (!h) throw std::runtime_error("libcurl could not create a handle");
    return h;
  }
  void release(CURL* h) { curl_easy_cleanup(h); }
  CURLSH* share() const { return share_; }

 private:
  static void lock(CURL*, curl_lock_data data, curl_lock_access, void* self) {
    static_cast<Client*>(self)->locks_[std::size_t(data) % kLocks].lock();
  }
  static void unlock(CURL*, curl_lock_data data, void* self) {
    static_cast<Client*>(self)->locks_[std::size_t(data) % kLocks].unlock();
  }
  static constexpr std::size_t kLocks = CURL_LOCK_DATA_LAST;
  CURLSH* share_ = nullptr;
  std::mutex locks_[kLocks];
};

Client& client() {
  static Client* c = new Client;
  return *c;
}

struct Handle {
  CURL* h = client().acquire();
  ~Handle() { client().release(h); }
};

struct Response {
  CURLcode code = CURLE_OK;
  long status = 0;
  std::string reason;         // the status line's reason phrase (HTTP/1.x)
  std::string content_range;  // of the last response (redirects reset it)
  std::vector<std::byte> body;
  std::uint64_t limit = kMaxBodyBytes;  // largest body accepted
  long current_status = 0;              // of the response whose headers are arriving
  std::uint64_t announced = 0;          // its Content-Length, when past `limit`
  bool too_large = false;
  char error[CURL_ERROR_SIZE] = {};
};

std::size_t on_body(char* p, std::size_t size, std::size_t n, void* user) {
  Response& r = *static_cast<Response*>(user);
  const std::size_t bytes = size * n;
  if (bytes > r.limit - std::min<std::uint64_t>(r.body.size(), r.limit)) {
    r.too_large = true;
    return 0;  // aborts the transfer (CURLE_WRITE_ERROR)
  }
  const auto* b = reinterpret_cast<const std::byte*>(p);
  r.body.insert(r.body.end(), b, b + bytes);
  return bytes;
}

std::string trim(std::string s) {
  while (!s.empty() && (s.back() == '\r' || s.back() == '\n' || s.back() == ' ')) s.pop_back();
  std::size_t i = 0;
  while (i < s.size() && s[i] == ' ') ++i;
  return s.substr(i);
}

std::size_t on_header(char* p, std::size_t size, std::size_t n, void* user) {
  Response& r = *static_cast<Response*>(user);
  const std::string line(p, size * n);
  if (line.rfind("HTTP/", 0) == 0) {
    // A new response (after a redirect or a 100 Continue): "HTTP/1.1 503 Service Unavailable".
    r.content_range.clear();
    const std::size_t a = line.find(' ');
    const std::size_t b = a == std::string::npos ? a : line.find(' ', a + 1);
    r.reason = b == std::string::npos ? std::string() : trim(line.substr(b + 1));
    r.current_status = a == std::string::npos ? 0 : std::strtol(line.c_str() + a + 1, nullptr, 10);
  } else if (line.size() > 15 && strncasecmp(line.c_str(), "content-length:", 15) == 0) {
    // A body announced past the bound is refused before any of it is read (a redirect's or an error's
    // body is not kept, so only a success counts).
    const std::string v = trim(line.substr(15));
    char* end = nullptr;
    const unsigned long long n = std::strtoull(v.c_str(), &end, 10);
    if (r.current_status >= 200 && r.current_status < 300 && !v.empty() && std::isdigit(static_cast<unsigned char>(v[0])) &&
        end != v.c_str() && n > r.limit) {
      r.too_large = true;
      r.announced = n;
      return 0;  // aborts the transfer
    }
  } else if (line.size() > 14 && strncasecmp(line.c_str(), "content-range:", 14) == 0) {
    r.content_range = trim(line.substr(14));
  }
  return size * n;
}

// Failures of the transfer that another try may not meet: the network, the server going away, a
// stall past the timeout, a body shorter than announced.
bool transient(CURLcode c) {
  switch (c) {
    case CURLE_COULDNT_RESOLVE_HOST:
    case CURLE_COULDNT_RESOLVE_PROXY:
    case CURLE_COULDNT_CONNECT:
    case CURLE_OPERATION_TIMEDOUT:
    case CURLE_PARTIAL_FILE:
    case CURLE_RECV_ERROR:
    case CURLE_SEND_ERROR:
    case CURLE_GOT_NOTHING:
    case CURLE_HTTP2:
    case CURLE_HTTP2_STREAM:
    case CURLE_SSL_CONNECT_ERROR:
      return true;
    default:
      return false;
  }
}

std::string status_text(const Response& r) {
  return "HTTP " + std::to_string(r.status) + (r.reason.empty() ? std::string() : " " + r.reason);
}

// "bytes a-b/total" (total may be "*"); false when malformed.
bool parse_content_range(const std::string& s, std::uint64_t& a, std::uint64_t& b, std::uint64_t& total,
                         bool& total_known) {
  unsigned long long x = 0, y = 0, t = 0;
  char star = 0;
  if (std::sscanf(s.c_str(), "bytes %llu-%llu/%llu", &x, &y, &t) == 3) {
    total_known = true;
  } else if (std::sscanf(s.c_str(), "bytes %llu-%llu/%c", &x, &y, &star) == 3 && star == '*') {
    total_known = false;
  } else {
    return false;
  }
  if (y < x) return false;
  a = x;
  b = y;
  total = t;
  return true;
}

long env_long(const char* name, double lo, double hi, double scale) {
  const char* v = std::getenv(name);
  if (!v || !*v) return -1;
  char* end = nullptr;
  const double d = std::strtod(v, &end);
  if (*end != '\0' || !(d >= lo && d <= hi)) {
    char buf[96];
    std::snprintf(buf, sizeof buf, "expected a number from %g to %g, got '", lo, hi);
    throw InputError(name, buf + std::string(v) + "'");
  }
  return long(std::ceil(d * scale));
}

// The Range header's value: "a-b", "-n" for a suffix; empty for the whole object.
std::string range_text(const HttpByteStore::Range& r) {
  if (r.suffix) return "-" + std::to_string(r.n);
  return r.n > 0 ? std::to_string(r.offset) + "-" + std::to_string(r.offset + r.n - 1) : "";
}

bool is_ranged(const HttpByteStore::Range& r) { return r.suffix || r.n > 0; }

// One try: the request on a fresh handle (connections come from the share), counted.
Response perform(const std::string& u, const HttpByteStore::Range& r, const HttpOptions& options, std::uint64_t limit) {
  HttpCounters& counters = http_counters();
  const std::string range = range_text(r);
  Response res;
  res.limit = limit;
  {
    Handle h;
    curl_easy_setopt(h.h, CURLOPT_SHARE, client().share());
    curl_easy_setopt(h.h, CURLOPT_URL, u.c_str());
    curl_easy_setopt(h.h, CURLOPT_PROTOCOLS_STR, "http,https");
    curl_easy_setopt(h.h, CURLOPT_REDIR_PROTOCOLS_STR, "http,https");
    curl_easy_setopt(h.h, CURLOPT_FOLLOWLOCATION, 1L);
    curl_easy_setopt(h.h, CURLOPT_MAXREDIRS, 5L);
    curl_easy_setopt(h.h, CURLOPT_NOSIGNAL, 1L);  // timeouts without SIGALRM: the loader is threaded
    curl_easy_setopt(h.h, CURLOPT_CONNECTTIMEOUT_MS, options.connect_timeout_ms);
    curl_easy_setopt(h.h, CURLOPT_TIMEOUT_MS, options.timeout_ms);
    curl_easy_setopt(h.h, CURLOPT_LOW_SPEED_LIMIT, 1L);
    curl_easy_setopt(h.h, CURLOPT_LOW_SPEED_TIME, options.low_speed_time_s);
    curl_easy_setopt(h.h, CURLOPT_USERAGENT, "sparseleap");
    curl_easy_setopt(h.h, CURLOPT_ERRORBUFFER, res.error);
    curl_easy_setopt(h.h, CURLOPT_WRITEFUNCTION, &on_body);
    curl_easy_setopt(h.h, CURLOPT_WRITEDATA, &res);
    curl_easy_setopt(h.h, CURLOPT_HEADERFUNCTION, &on_header);
    curl_easy_setopt(h.h, CURLOPT_HEADERDATA, &res);
    if (is_ranged(r)) curl_easy_setopt(h.h, CURLOPT_RANGE, range.c_str());
    res.code = curl_easy_perform(h.h);
    curl_easy_getinfo(h.h, CURLINFO_RESPONSE_CODE, &res.status);
    long connects = 0;
    curl_easy_getinfo(h.h, CURLINFO_NUM_CONNECTS, &connects);
    counters.connections.fetch_add(std::uint64_t(std::max(connects, 0L)), std::memory_order_relaxed);
  }
  counters.requests.fetch_add(1, std::memory_order_relaxed);
  counters.bytes.fetch_add(res.body.size(), std::memory_order_relaxed);
  return res;
}

// What a try's answer means: the bytes (nullopt: no such object), or with `failure` set a transient
// failure, tried again. Anything else throws.
struct Answer {
  std::optional<std::vector<std::byte>> bytes;
  std::string failure;
};

Answer failed(std::string why) { return {std::nullopt, std::move(why)}; }

// A transfer that did not complete: transient (tried again) or not (thrown).
Answer transfer_failure(const Response& res, const std::string& u) {
  if (res.too_large) {
    throw InputError(u, (res.announced ? "the answer announces " + bytes_text(res.announced) + ", over"
                                       : std::string("the answer holds more than")) +
                            " the " + bytes_text(res.limit) + " bound for this read");
  }
  // curl's own text, and the detail (host, port, elapsed time) when it gives one.
  std::string why = curl_easy_strerror(res.code);
  if (res.error[0] && why.find(res.error) == std::string::npos && std::string(res.error).find(why) == std::string::npos) {
    why += std::string(" (") + res.error + ")";
  } else if (res.error[0]) {
    why = res.error;
  }
  // libcurl says "Out of memory" for an answer whose header lines pass its bound: name what happened.
  if (res.code == CURLE_OUT_OF_MEMORY) why = "the answer's headers exceed libcurl's bound (" + why + ")";
  if (!transient(res.code)) throw InputError(u, why);
  return failed(why);
}

// A 200 to a range request: the server ignored Range and sent everything, so the slice is taken.
Answer whole_for_range(const Response& res, const HttpByteStore::Range& r, const std::string& u) {
  http_counters().whole_for_range.fetch_add(1, std::memory_order_relaxed);
  const std::uint64_t size = res.body.size();
  if (r.suffix && r.n > size) {
    throw InputError(u, "object has " + std::to_string(size) + " bytes, fewer than the " + std::to_string(r.n) +
                            "-byte suffix asked for");
  }
  if (!r.suffix && (r.offset > size || r.n > size - r.offset)) {
    throw InputError(u, "byte range " + std::to_string(r.offset) + "+" + std::to_string(r.n) +
                            " lies past the end of the " + std::to_string(size) + "-byte object");
  }
  const std::uint64_t first = r.suffix ? size - r.n : r.offset;
  return {std::vector<std::byte>(res.body.begin() + std::ptrdiff_t(first), res.body.begin() + std::ptrdiff_t(first + r.n)),
          {}};
}

// A 206 to a range request: its Content-Range must be the range asked for, its body complete.
Answer partial_content(Response& res, const HttpByteStore::Range& r, const std::string& u) {
  std::uint64_t a = 0, b = 0, total = 0;
  bool total_known = false;
  if (!parse_content_range(res.content_range, a, b, total, total_known)) {
    throw InputError(u, "206 answer without a valid Content-Range ('" + res.content_range + "')");
  }
  if (r.suffix && total_known && total < r.n) {
    throw InputError(u, "object has " + std::to_string(total) + " bytes, fewer than the " + std::to_string(r.n) +
                            "-byte suffix asked for");
  }
  const std::uint64_t want_a = r.suffix ? (total_known ? total - r.n : a) : r.offset;
  if (a != want_a || b - a + 1 != r.n) {
    if (!r.suffix && a == r.offset && total_known && b + 1 == total) {
      throw InputError(u, "byte range " + std::to_string(r.offset) + "+" + std::to_string(r.n) +
                              " lies past the end of the " + std::to_string(total) + "-byte object");
    }
    throw InputError(u, "asked for bytes " + range_text(r) + ", the server sent '" + res.content_range + "'");
  }
  if (res.body.size() != r.n) {
    return failed("truncated range answer (" + std::to_string(res.body.size()) + " of " + std::to_string(r.n) + " bytes)");
  }
  return {std::move(res.body), {}};
}

Answer interpret(Response res, const HttpByteStore::Range& r, const std::string& u) {
  const bool ranged = is_ranged(r);
  if (res.code != CURLE_OK) return transfer_failure(res, u);
  if (res.status == 404 || res.status == 410) return {};
  if (res.status == 200 && !ranged) return {std::move(res.body), {}};
  if (res.status == 200) return whole_for_range(res, r, u);
  if (res.status == 206 && ranged) return partial_content(res, r, u);
  if (res.status == 416) {
    throw InputError(u, "byte range " + range_text(r) + " lies past the end of the object (" + status_text(res) +
                            (res.content_range.empty() ? "" : ", " + res.content_range) + ")");
  }
  if (res.status == 408 || res.status == 429 || (res.status >= 500 && res.status < 600)) return failed(status_text(res));
  throw InputError(u, status_text(res));
}

}  // namespace

HttpOptions http_options_from_env() {
  HttpOptions o;
  if (const long ms = env_long("SPARSELEAP_HTTP_TIMEOUT", 0.01, 3600, 1000.0); ms > 0) {
    o.timeout_ms = ms;
    o.connect_timeout_ms = std::min(o.connect_timeout_ms, ms);
    o.low_speed_time_s = std::clamp((ms + 999) / 1000, 1L, o.low_speed_time_s);
  }
  if (const long t = env_long("SPARSELEAP_HTTP_TRIES", 1, 20, 1.0); t > 0) o.tries = int(t);
  return o;
}

HttpCounters& http_counters() {
  static HttpCounters c;
  return c;
}

HttpByteStore::HttpByteStore(std::string base, HttpOptions options) : base_(std::move(base)), options_(options) {
  while (!base_.empty() && base_.back() == '/') base_.pop_back();
  client();  // curl_global_init before any thread uses the client
}

std::string HttpByteStore::url(const std::string& key) const { return store_url(base_, key); }

std::optional<std::vector<std::byte>> HttpByteStore::read(const std::string& key, std::uint64_t max_bytes) const {
  return fetch(key, {}, max_bytes);
}

std::optional<std::vector<std::byte>> HttpByteStore::read_range(const std::string& key, std::uint64_t offset,
                                                                std::uint64_t n) const {
  if (n == 0) return std::vector<std::byte>();  // "bytes=a-(a-1)" is no range; nothing to fetch
  return fetch(key, {false, offset, n}, kMaxBodyBytes);
}

std::optional<std::vector<std::byte>> HttpByteStore::read_suffix(const std::string& key, std::uint64_t n) const {
  SL_CHECK(n > 0);
  return fetch(key, {true, 0, n}, kMaxBodyBytes);
}

std::optional<std::vector<std::byte>> HttpByteStore::fetch(const std::string& key, Range r, std::uint64_t limit) const {
  const std::string u = url(key);
  HttpCounters& counters = http_counters();
  long wait_ms = options_.backoff_ms;
  for (int attempt = 1;; ++attempt) {
    Answer a = interpret(perform(u, r, options_, limit), r, u);
    if (a.failure.empty()) return std::move(a.bytes);
    if (attempt >= options_.tries) {
      counters.failed.fetch_add(1, std::memory_order_relaxed);
      throw TransientError(u, a.failure + " (gave up after " + std::to_string(attempt) +
                                  (attempt == 1 ? " try)" : " tries)"));
    }
    counters.retries.fetch_add(1, std::memory_order_relaxed);
    std::this_thread::sleep_for(std::chrono::milliseconds(wait_ms));
    wait_ms *= 2;
  }
}

}  // namespace sl
