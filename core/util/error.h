// Errors in user input: one exception type carrying the offending file and the reason.
// Libraries throw it; apps/ catches it once, prints one line and exits non-zero.
#pragma once

#include <stdexcept>
#include <string>

namespace sl {

class InputError : public std::runtime_error {
 public:
  InputError(std::string file, std::string reason)
      : std::runtime_error(file.empty() ? reason : file + ": " + reason),
        file_(std::move(file)),
        reason_(std::move(reason)) {}

  const std::string& file() const { return file_; }
  const std::string& reason() const { return reason_; }

 private:
  std::string file_;
  std::string reason_;
};

// A failure that may not recur when the same read is tried again: a timeout, a dropped connection, an
// HTTP 5xx, an injected transient fault. The brick loader retries these with backoff; any other
// InputError fails the brick for good. Wrapping layers that add context (store, level, chunk) must
// rethrow a TransientError as one, so the loader still sees it.
class TransientError : public InputError {
 public:
  using InputError::InputError;
};

}  // namespace sl
