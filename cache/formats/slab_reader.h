// The slab-reader interface: a volume file read z-slab by z-slab, front to back, in bounded memory.
// Implemented by the NRRD, TIFF-stack and NIfTI readers; used by `ingest` (ingest.h).
#pragma once

#include <cstddef>

#include "core/scene/volume.h"

namespace sl {

// A volume read z-slab by z-slab, front to back.
class SlabReader {
 public:
  virtual ~SlabReader() = default;
  virtual const VolumeDesc& desc() const = 0;
  // Reads z-planes [z0, z0 + nz) into dst (x fastest, native byte order). Calls come in order with
  // contiguous ranges starting at 0. Throws InputError(path, reason) for bad or short data.
  virtual void read(int z0, int nz, std::byte* dst) = 0;
};

}  // namespace sl
