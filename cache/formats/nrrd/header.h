// NRRD internals shared by read_nrrd and read_nrrd_header (nrrd.cpp, header.cpp) and the streaming reader
// (slabs.cpp): the header parse, opening the data it describes, byte swapping.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>

#include "core/scene/volume.h"

namespace sl::nrrd_detail {

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};
using File = std::unique_ptr<std::FILE, FileCloser>;

std::string errno_text();
std::string lower(std::string s);

// Opens for reading; `who` is the file the error names (the header, for a detached data file), and
// `what` prefixes the reason so the user knows which of the two files is at fault.
File open_read(const std::string& path, const std::string& who, const std::string& what);

struct Header {
  VolumeDesc desc;
  bool gzip = false;
  bool big_endian = false;
  std::string data_file;          // resolved path of a detached data file; empty when attached
  std::uint64_t data_offset = 0;  // attached: first byte after the header's blank line
  std::int64_t byte_skip = 0;     // -1: the data are the last bytes of the file (raw only)
  std::int64_t line_skip = 0;
};

// Parses and checks the header of `path`: magic, required fields, type, sizes (including that the
// byte count fits in 64 bits), encoding, endianness, spacing and where the data are. Applies no
// memory limit and does not look at the data.
Header parse_header(const std::string& path);

// The data `h` describes, opened: the detached data file, or `path` just after its header; past the
// `line skip` lines. `where` prefixes the errors about a detached data file ("data file 'x.raw': ").
struct DataFile {
  File file;
  std::string where;
};
DataFile open_data(const Header& h, const std::string& path);

// Reverses the bytes of each of `count` items of `size` bytes (a byte-order change).
void swap_bytes(std::byte* p, std::uint64_t count, int size);

}  // namespace sl::nrrd_detail
