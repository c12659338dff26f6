// HttpByteStore: a chunked store (Zarr v2/v3, precomputed) read over HTTP(S) with libcurl.
//
// One process-wide client: easy handles (one per request) sharing one CURLSH connection and DNS cache, so the
// loader threads run requests in parallel and each reuses a kept-alive connection. Objects are GETs,
// byte ranges `Range: bytes=a-b` (checked against the 206's Content-Range; a 200 carrying the whole
// object is sliced and counted), suffix ranges `bytes=-n` (a shard index at the end). 404/410 = the
// object does not exist (a chunk never written: the fill value). 401/403 and other 4xx = an error naming
// the URL. 5xx, 408/429, timeouts, dropped connections and truncated bodies are retried inside the
// client with exponential backoff; if every try fails, sl::TransientError (the brick loader's retry and
// out-of-core fault path takes it from there, core/util/error.h).
#pragma once

#include <atomic>
#include <cstdint>
#include <string>

#include "cache/stores/byte_store.h"

namespace sl {

struct HttpOptions {
  long connect_timeout_ms = 10000;
  long timeout_ms = 60000;         // one whole request
  long low_speed_time_s = 20;      // abort a transfer slower than 1 byte/s for this long (a stall)
  int tries = 4;                   // attempts per request
  long backoff_ms = 100;           // wait before the second try; doubled for each further one
};

// The options from the environment: SPARSELEAP_HTTP_TIMEOUT (seconds per request, also bounding the
// connect and stall times), SPARSELEAP_HTTP_TRIES. Bad values throw InputError naming the variable.
HttpOptions http_options_from_env();

// What every HttpByteStore of the process did, for the render summary and the closing note.
struct HttpCounters {
  std::atomic<std::uint64_t> requests{0};     // HTTP requests sent (each try counts)
  std::atomic<std::uint64_t> connections{0};  // new connections they opened (the rest reused one)
  std::atomic<std::uint64_t> bytes{0};        // body bytes received
  std::atomic<std::uint64_t> retries{0};      // tries after a transient failure
  std::atomic<std::uint64_t> failed{0};       // reads that failed after every try (TransientError)
  std::atomic<std::uint64_t> whole_for_range{0};  // range requests the server answered with 200 + all
};
HttpCounters& http_counters();

class HttpByteStore final : public ByteStore {
 public:
  // `base` is http://… or https://… (no trailing slash needed); keys are appended after a '/'.
  explicit HttpByteStore(std::string base, HttpOptions options = http_options_from_env());

  std::optional<std::vector<std::byte>> read(const std::string& key, std::uint64_t max_bytes) const override;
  std::optional<std::vector<std::byte>> read_range(const std::string& key, std::uint64_t offset,
                                                   std::uint64_t n) const override;
  std::optional<std::vector<std::byte>> read_suffix(const std::string& key, std::uint64_t n) const override;

  const std::string& base() const { return base_; }
  // The URL of `key` (store_key.h: refused when it could leave the base).
  std::string url(const std::string& key) const;

  // What one read asks for.
  struct Range {
    bool suffix = false;
    std::uint64_t offset = 0, n = 0;  // n == 0 with !suffix: the whole object
  };

 private:
  std::optional<std::vector<std::byte>> fetch(const std::string& key, Range r, std::uint64_t limit) const;

  std::string base_;
  HttpOptions options_;
};

}  // namespace sl
