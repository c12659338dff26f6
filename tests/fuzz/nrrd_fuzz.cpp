// NRRD header and data (cache/formats/nrrd/: the whole-file reader and the streaming slab reader): the input is the
// file; a part after the line "--data-file--" becomes `data.raw` beside it, for detached headers
// (`data file: data.raw`). Both readers run: read_nrrd (whole volume) and the slab reader.
#include <cstdint>
#include <vector>

#include "cache/formats/nrrd/nrrd.h"
#include "core/util/error.h"
#include "tests/fuzz/fuzz_util.h"

SL_FUZZ_TARGET(input) {
  const auto parts = sl::fuzz::split(input, "\n--data-file--\n", 2);
  const auto& dir = sl::fuzz::scratch().reset();
  const std::string path = (dir / "in.nrrd").string();
  sl::fuzz::write_file(path, parts[0]);
  if (parts.size() > 1) sl::fuzz::write_file(dir / "data.raw", parts[1]);
  const auto d = sl::fuzz::accepted([&] { return sl::read_nrrd_header(path); });
  if (d && d->byte_size() <= sl::fuzz::kMaxVolumeBytes) {
    if (const auto v = sl::fuzz::accepted([&] { return sl::read_nrrd(path); })) {
      if (v->desc().dims != d->dims || v->type() != d->type) std::abort();  // the header read disagrees
    }
  }
  sl::fuzz::accepted([&] {
    const auto r = sl::open_nrrd_slabs(path);
    const sl::VolumeDesc& rd = r->desc();
    if (rd.byte_size() > sl::fuzz::kMaxVolumeBytes) return false;
    const std::size_t plane = std::size_t(rd.dims.x) * std::size_t(rd.dims.y) * std::size_t(sl::voxel_size(rd.type));
    std::vector<std::byte> slab(plane * 4);
    for (int z = 0; z < rd.dims.z; z += 4) r->read(z, std::min(4, rd.dims.z - z), slab.data());
    return true;
  });
}
