// Store key resolution (cache/stores/store_key.h): the input is a key as a store's metadata could
// write it. Either store_key refuses it, or the object it names lies inside the store, both as a local
// path (resolved lexically) and as a URL after what a server does to a path (percent-decoding, as often
// as a chain of servers might, backslashes read as '/', dot segments removed).
#include <filesystem>
#include <string>
#include <vector>

#include "cache/stores/store_key.h"
#include "tests/fuzz/fuzz_util.h"
#include "tests/server_path.h"

SL_FUZZ_TARGET(input) {
  std::string normal;
  try {
    normal = sl::store_key(input);
  } catch (const std::runtime_error&) {
    return;  // refused: nothing is read
  }
  const std::string url = sl::store_url("http://host/data/s.zarr", input);
  if (url.rfind("http://host/", 0) != 0) __builtin_trap();
  const std::string served = sl::test::server_path(url.substr(11));
  if (!(served == "/data/s.zarr" || served.rfind("/data/s.zarr/", 0) == 0)) __builtin_trap();
  const std::string local = std::filesystem::path(sl::local_store_path("/data/s.zarr", input)).lexically_normal().string();
  if (!(local == "/data/s.zarr" || local == "/data/s.zarr/" || local.rfind("/data/s.zarr/", 0) == 0)) __builtin_trap();
  // The normal form is a fixed point.
  if (sl::store_key(normal) != normal) __builtin_trap();
  for (const char c : normal) {
    if (c == '\0' || c == '\\' || c == '?' || c == '#') __builtin_trap();
  }
}
