// TIFF stacks (cache/formats/tiff_stack.cpp): the input is one (multipage) .tif, read whole.
#include <cstdint>

#include "cache/formats/volume_file.h"
#include "core/error.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = (sl::fuzz::scratch().reset() / "in.tif").string();
  sl::fuzz::write_file(path, sl::fuzz::as_text(data, size));
  try {
    if (sl::read_volume_file_desc(path).byte_size() > sl::fuzz::kMaxVolumeBytes) return 0;
    sl::read_volume_file(path);
  } catch (const sl::InputError&) {
  }
  return 0;
}
