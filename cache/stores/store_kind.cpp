#include "cache/stores/store_kind.h"

#include <filesystem>
#include <string_view>

#include "cache/stores/store_url.h"

namespace sl {
namespace {

namespace fs = std::filesystem;

// A local Zarr store: named so, or a directory holding .zattrs, .zgroup, .zarray or (v3) zarr.json.
bool local_zarr(const std::string& path) {
  if (named_zarr(path)) return true;
  std::string p = path;
  while (p.size() > 1 && p.back() == '/') p.pop_back();
  std::error_code ec;
  const fs::path d(p);
  return fs::is_directory(d, ec) && (fs::exists(d / ".zattrs", ec) || fs::exists(d / ".zgroup", ec) ||
                                     fs::exists(d / ".zarray", ec) || fs::exists(d / "zarr.json", ec));
}

}  // namespace

StoreLocation split_kind_prefix(const std::string& spec) {
  struct Prefix {
    std::string_view text;
    StoreKind kind;
  };
  constexpr Prefix kPrefixes[] = {{"precomputed://", StoreKind::Precomputed},
                                  {"zarr://", StoreKind::Zarr},
                                  {"zarr2://", StoreKind::Zarr},
                                  {"zarr3://", StoreKind::Zarr}};
  for (const Prefix& p : kPrefixes) {
    if (spec.starts_with(p.text)) return {p.kind, spec.substr(p.text.size())};
  }
  return {StoreKind::None, spec};
}

bool named_zarr(std::string path) {
  while (path.size() > 1 && path.back() == '/') path.pop_back();
  return path.size() >= 5 && path.compare(path.size() - 5, 5, ".zarr") == 0;
}

StoreLocation recognise_store(const std::string& path) {
  if (const StoreLocation prefixed = split_kind_prefix(path); prefixed.kind != StoreKind::None) {
    // precomputed://https://… is remote (store_url.h); precomputed:///data/em a local directory, checked
    // when it is opened.
    if (is_url(prefixed.path)) return recognise_url(path);
    return prefixed;
  }
  if (is_url(path)) return recognise_url(path);  // http(s)://…, or an unsupported scheme it names
  if (local_zarr(path)) return {StoreKind::Zarr, path};
  std::error_code ec;
  const fs::path d(path);
  // An `info` of any kind (a FIFO, a symlink loop) makes it precomputed: that reader then names what is
  // wrong with it.
  if (fs::is_directory(d, ec) && fs::exists(fs::symlink_status(d / "info", ec))) return {StoreKind::Precomputed, path};
  return {StoreKind::None, path};
}

}  // namespace sl
