// What a volume path names, decided in one place for every front end (render, bench, view, info) and
// every way a store can be reached: a local directory recognised by what it holds (Zarr's zarr.json or
// .zattrs/.zgroup/.zarray, Neuroglancer precomputed's `info`), or any path behind a kind prefix
// (`precomputed://DIR`, `zarr://DIR`). URL schemes (http://, https://) extend this function (store_url.h).
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

}  // namespace sl
