// What a volume path names, decided in one place for every front end (render, bench, view, info) and
// every way a store can be reached: a local directory recognised by what it holds (Zarr's zarr.json or
// .zattrs/.zgroup/.zarray, Neuroglancer precomputed's `info`), or any path behind a kind prefix
// (`precomputed://DIR`, `zarr://DIR`). URL schemes (http://, https://) extend this function (store_url.h).
// Only object names are looked at here; what the objects mean is for the readers in cache/formats/.
#pragma once

#include <string>

namespace sl {

enum class StoreKind { None, Zarr, Precomputed };

struct StoreLocation {
  StoreKind kind = StoreKind::None;  // None: a volume file (NRRD, NIfTI, TIFF) or a spec, not a store
  std::string path;                  // the path with any kind prefix removed
};

// Recognises `path`. A prefix wins over what the directory holds; an unprefixed path that holds neither
// store's metadata is StoreKind::None (its own reader then names what is wrong with it).
StoreLocation recognise_store(const std::string& path);

// The kind a Neuroglancer kind prefix names (`zarr://`, and its aliases `zarr2://` and `zarr3://`, whose
// Zarr version is still read from the store; `precomputed://`) and `spec` without it; {None, spec} when
// `spec` has none.
StoreLocation split_kind_prefix(const std::string& spec);

// True when `path` (a directory or URL) ends in .zarr, optionally followed by slashes: a Zarr store by
// its name, even before it exists.
bool named_zarr(std::string path);

}  // namespace sl
