// A command's output files as one set: every one checked before the (slow) work, written in order,
// and on a failure part-way (a full disk at the last file) the ones already written by this run
// removed again, so a failed command never leaves a complete-looking subset behind (DESIGN.md
// "Conventions").
#pragma once

#include <functional>
#include <string>
#include <vector>

namespace sl::app {

// PREFIX + ext, or PREFIX itself when it is a character device or FIFO (`--out /dev/null`): a stream
// takes every image in place (core/util/atomic_file.h) instead of a file created beside it.
std::string output_with_extension(const std::string& prefix, const std::string& ext);

class OutputFiles {
 public:
  // Registers an output and the other files its writer creates beside it (a detached NRRD's data
  // file); errors name `path`. Checked at once (check_output_file): a
  // missing folder, a directory or a device in the way is an error before anything is computed.
  void add(const std::string& path, std::vector<std::string> also = {});
  // Writes output `path` (registered) with `write`; when it throws, the outputs this object wrote
  // before are removed (streams are left alone) and the error passes on.
  void write(const std::string& path, const std::function<void(const std::string&)>& write);

 private:
  struct Output {
    std::string path;
    std::vector<std::string> files;  // path and the files beside it
  };
  std::vector<Output> registered_;
  std::vector<std::string> written_;  // files
};

}  // namespace sl::app
