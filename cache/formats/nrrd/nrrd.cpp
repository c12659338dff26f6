#include "cache/formats/nrrd/nrrd.h"

#include <zlib.h>

#include <algorithm>
#include <bit>
#include <charconv>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <new>
#include <vector>

#include "cache/formats/nrrd/header.h"
#include "core/util/atomic_file.h"
#include "core/util/error.h"

// NRRD data: reading the payload described by a parsed header (header.cpp), and writing.
namespace sl {
namespace {

namespace fs = std::filesystem;
using nrrd_detail::errno_text;
using nrrd_detail::File;
using nrrd_detail::Header;
using nrrd_detail::swap_bytes;

constexpr std::size_t kChunk = std::size_t(1) << 20;  // I/O and zlib buffer size
// zlib counts in 32-bit uInt, so large volumes go through it in pieces of at most this size.
constexpr std::uint64_t kZlibPiece = std::uint64_t(1) << 30;

std::string fmt_bytes(std::uint64_t n) { return std::to_string(n) + (n == 1 ? " byte" : " bytes"); }

// Positions `f` at the raw data and checks that they are all there, before anything is allocated.
void seek_raw(std::FILE* f, const std::string& path, const std::string& where, const Header& h,
              std::uint64_t need) {
  std::int64_t pos = ftello(f);
  if (fseeko(f, 0, SEEK_END) != 0) throw InputError(path, where + "cannot seek: " + errno_text());
  const std::int64_t size = ftello(f);
  if (h.byte_skip == -1) {
    pos = std::max<std::int64_t>(pos, size - std::int64_t(need));  // data are the file's last bytes
  } else {
    pos += h.byte_skip;
  }
  const std::uint64_t avail = size > pos ? std::uint64_t(size - pos) : 0;
  if (avail < need) {
    throw InputError(path, where + "data truncated: expected " + fmt_bytes(need) + " of raw data, found " +
                               std::to_string(avail));
  }
  // Extra bytes after the data are ignored (teem does the same; some writers pad).
  if (fseeko(f, pos, SEEK_SET) != 0) throw InputError(path, where + "cannot seek: " + errno_text());
}

void read_raw(std::FILE* f, const std::string& path, const std::string& where, std::byte* dst,
              std::uint64_t need) {
  for (std::uint64_t done = 0; done < need;) {
    const std::size_t n = std::fread(dst + done, 1, std::size_t(std::min<std::uint64_t>(kChunk, need - done)), f);
    if (n == 0) throw InputError(path, where + "read error after " + fmt_bytes(done) + ": " + errno_text());
    done += n;
  }
}

// Inflates a gzip (or zlib) stream; `byte skip` counts decompressed bytes, as in teem.
void read_gzip(std::FILE* f, const std::string& path, const std::string& where, const Header& h,
               std::byte* dst, std::uint64_t need) {
  z_stream zs{};
  if (inflateInit2(&zs, 15 + 32) != Z_OK) throw std::bad_alloc();  // 15 + 32: detect gzip/zlib header
  struct End {
    z_stream* z;
    ~End() { inflateEnd(z); }
  } end{&zs};
  const std::uint64_t skip = std::uint64_t(h.byte_skip);
  const std::uint64_t want = skip + need;
  std::vector<unsigned char> in(kChunk), scratch(std::size_t(1) << 16);
  std::uint64_t total = 0;  // decompressed bytes so far
  bool ended = false;
  while (!ended) {
    if (zs.avail_in == 0) {
      const std::size_t n = std::fread(in.data(), 1, in.size(), f);
      if (n == 0) {
        if (std::ferror(f)) throw InputError(path, where + "read error: " + errno_text());
        break;  // compressed input exhausted before the stream's end
      }
      zs.next_in = in.data();
      zs.avail_in = uInt(n);
    }
    // Route output: skipped bytes and anything past the expected size go to scratch.
    unsigned char* out = scratch.data();
    std::uint64_t room = scratch.size();
    if (total < skip) {
      room = std::min<std::uint64_t>(room, skip - total);
    } else if (total < want) {
      out = reinterpret_cast<unsigned char*>(dst) + (total - skip);
      room = std::min<std::uint64_t>(kZlibPiece, want - total);
    }
    zs.next_out = out;
    zs.avail_out = uInt(room);
    const int ret = inflate(&zs, Z_NO_FLUSH);
    total += room - zs.avail_out;
    if (total > want) {
      throw InputError(path, where + "gzip data decompress to more than the expected " + fmt_bytes(want));
    }
    if (ret == Z_STREAM_END) {
      ended = true;
    } else if (ret == Z_DATA_ERROR || ret == Z_NEED_DICT || ret == Z_STREAM_ERROR) {
      throw InputError(path, where + "gzip data are corrupt (zlib: " +
                                 (zs.msg ? zs.msg : "invalid stream") + ") after " +
                                 fmt_bytes(total) + " of " + std::to_string(want));
    } else if (ret == Z_MEM_ERROR) {
      throw std::bad_alloc();
    }  // Z_OK, or Z_BUF_ERROR meaning "needs more input": loop
  }
  if (total < want) {
    throw InputError(path, where + "gzip data truncated: expected " + fmt_bytes(want) +
                               " after decompression, found " + std::to_string(total));
  }
  if (!ended) throw InputError(path, where + "gzip stream truncated: it ends before its checksum");
}

}  // namespace

namespace nrrd_detail {

void swap_bytes(std::byte* p, std::uint64_t count, int size) {
  for (std::uint64_t i = 0; i < count; ++i, p += size) std::reverse(p, p + size);
}

DataFile open_data(const Header& h, const std::string& path) {
  const bool detached = !h.data_file.empty();
  DataFile d;
  d.where = detached ? "data file '" + h.data_file + "': " : "";
  d.file = open_read(detached ? h.data_file : path, path, d.where);
  if (!detached && fseeko(d.file.get(), off_t(h.data_offset), SEEK_SET) != 0) {
    throw InputError(path, "cannot seek: " + errno_text());
  }
  for (std::int64_t i = 0; i < h.line_skip; ++i) {
    int c;
    while ((c = std::getc(d.file.get())) != EOF && c != '\n') {
    }
    if (c == EOF) throw InputError(path, d.where + "data truncated: file ends within the skipped lines");
  }
  return d;
}

}  // namespace nrrd_detail

Volume read_nrrd(const std::string& path) {
  const Header h = nrrd_detail::parse_header(path);
  validate_desc(h.desc, path);
  nrrd_detail::DataFile data = nrrd_detail::open_data(h, path);
  const File& f = data.file;
  const std::string& where = data.where;

  const std::uint64_t need = h.desc.byte_size();
  if (!h.gzip) seek_raw(f.get(), path, where, h, need);
  Volume v(h.desc, path);
  if (h.gzip) {
    read_gzip(f.get(), path, where, h, v.data(), need);
  } else {
    read_raw(f.get(), path, where, v.data(), need);
  }
  const int size = voxel_size(h.desc.type);
  if (size > 1 && h.big_endian != (std::endian::native == std::endian::big)) {
    swap_bytes(v.data(), h.desc.voxel_count(), size);
  }
  return v;
}

namespace {

const char* nrrd_type(VoxelType t) {
  switch (t) {
    case VoxelType::U8: return "unsigned char";
    case VoxelType::U16: return "unsigned short";
    case VoxelType::U32: return "unsigned int";
    case VoxelType::F32: return "float";
  }
  return "?";
}

std::string shortest(float x) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, x);  // shortest text that reads back exactly
  return std::string(buf, r.ptr);
}

// Streams the volume as little-endian bytes to `sink(ptr, n)`, swapping a copy on big-endian hosts.
template <class Sink> void for_each_le_chunk(const Volume& v, Sink&& sink) {
  const std::uint64_t total = v.desc().byte_size();
  const int size = voxel_size(v.type());
  std::vector<std::byte> tmp;
  for (std::uint64_t done = 0; done < total;) {
    const std::uint64_t n = std::min<std::uint64_t>(kZlibPiece, total - done);
    const std::byte* p = v.data() + done;
    if (std::endian::native == std::endian::big && size > 1) {
      tmp.assign(p, p + n);
      swap_bytes(tmp.data(), n / std::uint64_t(size), size);
      p = tmp.data();
    }
    sink(p, std::size_t(n));
    done += n;
  }
}

void write_payload(AtomicFile& out, const Volume& v, bool gzip) {
  if (!gzip) {
    for_each_le_chunk(v, [&](const std::byte* p, std::size_t n) { out.write(p, n); });
    return;
  }
  z_stream zs{};
  // 15 + 16: a gzip wrapper (what teem writes and reads); default level balances time and size.
  if (deflateInit2(&zs, Z_DEFAULT_COMPRESSION, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY) != Z_OK) {
    throw std::bad_alloc();
  }
  struct End {
    z_stream* z;
    ~End() { deflateEnd(z); }
  } end{&zs};
  std::vector<unsigned char> buf(kChunk);
  const auto pump = [&](int flush) {
    int ret;
    do {
      zs.next_out = buf.data();
      zs.avail_out = uInt(buf.size());
      ret = deflate(&zs, flush);
      SL_CHECK(ret != Z_STREAM_ERROR);
      out.write(buf.data(), buf.size() - zs.avail_out);
    } while (zs.avail_out == 0 || (flush == Z_FINISH && ret != Z_STREAM_END));
  };
  for_each_le_chunk(v, [&](const std::byte* p, std::size_t n) {
    zs.next_in = reinterpret_cast<Bytef*>(const_cast<std::byte*>(p));
    zs.avail_in = uInt(n);
    pump(Z_NO_FLUSH);
  });
  pump(Z_FINISH);
}

}  // namespace

std::vector<std::string> nrrd_output_files(const std::string& path, bool gzip) {
  const fs::path out(path);
  if (nrrd_detail::lower(out.extension().string()) != ".nhdr") return {path};
  return {path, (out.parent_path() / (out.stem().string() + (gzip ? ".raw.gz" : ".raw"))).string()};
}

void write_nrrd(const std::string& path, const Volume& v, bool gzip) {
  const fs::path out(path);
  const std::string ext = nrrd_detail::lower(out.extension().string());
  if (ext != ".nrrd" && ext != ".nhdr") {
    throw InputError(path, "output name must end in .nrrd (attached) or .nhdr (detached header)");
  }
  if (v.empty()) throw InputError(path, "cannot write an empty volume");
  const VolumeDesc& d = v.desc();
  const bool detached = ext == ".nhdr";
  const std::vector<std::string> files = nrrd_output_files(path, gzip);
  const std::string data_name = detached ? fs::path(files[1]).filename().string() : std::string();

  std::string header = "NRRD0004\n";
  header += "# Complete NRRD file format specification at:\n";
  header += "# http://teem.sourceforge.net/nrrd/format.html\n";
  header += std::string("type: ") + nrrd_type(d.type) + "\n";
  header += "dimension: 3\n";
  header += "sizes: " + std::to_string(d.dims.x) + " " + std::to_string(d.dims.y) + " " +
            std::to_string(d.dims.z) + "\n";
  header += "spacings: " + shortest(d.spacing.x) + " " + shortest(d.spacing.y) + " " +
            shortest(d.spacing.z) + "\n";
  header += "kinds: domain domain domain\n";
  header += "endian: little\n";
  header += std::string("encoding: ") + (gzip ? "gzip" : "raw") + "\n";
  if (detached) {
    header += "data file: " + data_name + "\n";
  } else {
    header += "\n";  // the blank line that separates an attached header from its data
  }

  AtomicFile head(out, path);
  head.write(header);
  if (!detached) {
    write_payload(head, v, gzip);
    head.commit();
    return;
  }
  AtomicFile data(files[1], path);
  write_payload(data, v, gzip);
  data.close();
  head.close();
  // Data first: the header is what makes the pair look complete, so it appears last.
  data.commit();
  try {
    head.commit();
  } catch (...) {
    std::error_code ec;  // a data file without its header is debris: remove what we just wrote
    fs::remove(data.path(), ec);
    throw;
  }
}

}  // namespace sl
