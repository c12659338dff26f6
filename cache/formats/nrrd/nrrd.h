// NRRD volumes (teem's format, read and written by 3D Slicer, ITK, ParaView): readers and writer for
// the 3-D scalar volumes sparseleap renders (DESIGN.md "Data model").
// Spec: teem.sourceforge.net/nrrd/format.html
//
// Read: magic NRRD0001..NRRD0005, attached (.nrrd) or detached (header naming a `data file`, resolved
// relative to the header's directory), encodings raw and gzip, types uchar/ushort/uint/float under all
// their spec spellings, either endianness, `byte skip` / `line skip`, spacing from `spacings` or from
// the lengths of `space directions` (default 1). Field names and values are matched case-insensitively,
// comments and key/value pairs (`key:=value`) and fields sparseleap does not use are ignored. A missing
// `endian` means little. Raw data longer than needed are fine (the rest is ignored); a gzip stream must
// decompress to exactly the expected size. Multi-file data (`data file: LIST`) and the ascii, hex and
// bzip2 encodings are rejected with a clear message.
// Every problem with the input throws InputError(path, reason); nothing else escapes for bad files.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "cache/formats/slab_reader.h"
#include "core/scene/volume.h"

namespace sl {

// Reads a whole 3-D NRRD volume into memory (checked against validate_desc's memory limit).
Volume read_nrrd(const std::string& path);

// The NRRD reader streaming z-slab by z-slab (raw: sequential reads; gzip: inflated as it goes), for
// `ingest`. Checks the header like read_nrrd_header and that raw data are all there.
std::unique_ptr<SlabReader> open_nrrd_slabs(const std::string& path);

// Reads only the header: dims, spacing and type. Checks that the description is well formed but not
// that it fits in memory, so `info` can describe volumes larger than RAM. Does not touch the data.
VolumeDesc read_nrrd_header(const std::string& path);

// Writes `v` as NRRD0004, little-endian, with `spacings`. The form follows the name: `x.nrrd` is
// attached (header and data in one file); `x.nhdr` is a detached header beside `x.raw` (or `x.raw.gz`
// with gzip). Every file is written under a hidden temporary name in the destination directory and
// renamed only once complete, so a failure never leaves a file that looks finished. Throws InputError
// naming `path` when the name has another extension or a file cannot be written.
void write_nrrd(const std::string& path, const Volume& v, bool gzip = false);

// The files write_nrrd(path, .., gzip) writes: `path`, then for a detached header its data file.
std::vector<std::string> nrrd_output_files(const std::string& path, bool gzip);

}  // namespace sl
