// NRRD header and data (cache/formats/nrrd*.cpp, and ingest's streaming reader): the input is the
// file; a part after the line "--data-file--" becomes `data.raw` beside it, for detached headers
// (`data file: data.raw`). Both readers run: read_nrrd (whole volume) and the slab reader.
#include <cstdint>
#include <vector>

#include "cache/formats/ingest.h"
#include "cache/formats/nrrd.h"
#include "core/error.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto parts = sl::fuzz::split(sl::fuzz::as_text(data, size), "\n--data-file--\n", 2);
  const auto& dir = sl::fuzz::scratch().reset();
  const std::string path = (dir / "in.nrrd").string();
  sl::fuzz::write_file(path, parts[0]);
  if (parts.size() > 1) sl::fuzz::write_file(dir / "data.raw", parts[1]);
  try {
    const sl::VolumeDesc d = sl::read_nrrd_header(path);
    if (d.byte_size() > sl::fuzz::kMaxVolumeBytes) return 0;
    const sl::Volume v = sl::read_nrrd(path);
    if (v.desc().dims != d.dims || v.type() != d.type) std::abort();  // the header read disagrees
  } catch (const sl::InputError&) {
  }
  try {
    const auto r = sl::open_nrrd_slabs(path);
    const sl::VolumeDesc& d = r->desc();
    if (d.byte_size() > sl::fuzz::kMaxVolumeBytes) return 0;
    const std::size_t plane = std::size_t(d.dims.x) * std::size_t(d.dims.y) * std::size_t(sl::voxel_size(d.type));
    std::vector<std::byte> slab(plane * 4);
    for (int z = 0; z < d.dims.z; z += 4) r->read(z, std::min(4, d.dims.z - z), slab.data());
  } catch (const sl::InputError&) {
  }
  return 0;
}
