#include "cache/stores/store_kind.h"

#include <filesystem>

#include "cache/formats/zarr/meta.h"
#include "cache/stores/store_url.h"

namespace sl {

StoreLocation recognise_store(const std::string& path) {
  // Neuroglancer's kind prefixes; zarr2:// and zarr3:// are aliases of zarr:// (the version is read
  // from the store).
  struct Prefix {
    std::string_view text;
    StoreKind kind;
  };
  constexpr Prefix kPrefixes[] = {{"precomputed://", StoreKind::Precomputed},
                                  {"zarr://", StoreKind::Zarr},
                                  {"zarr2://", StoreKind::Zarr},
                                  {"zarr3://", StoreKind::Zarr}};
  for (const Prefix& p : kPrefixes) {
    if (!path.starts_with(p.text)) continue;
    const std::string rest = path.substr(p.text.size());
    // precomputed://https://… is remote (store_url.h); precomputed:///data/em a local directory, checked
    // when it is opened.
    if (is_url(rest)) return recognise_url(path);
    return {p.kind, rest};
  }
  if (is_url(path)) return recognise_url(path);  // http(s)://…, or an unsupported scheme it names
  if (zarr::is_zarr_path(path)) return {StoreKind::Zarr, path};
  std::error_code ec;
  const std::filesystem::path d(path);
  if (std::filesystem::is_directory(d, ec) && std::filesystem::is_regular_file(d / "info", ec)) {
    return {StoreKind::Precomputed, path};
  }
  return {StoreKind::None, path};
}

}  // namespace sl
