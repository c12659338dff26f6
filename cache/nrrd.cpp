#include "cache/nrrd.h"

#include <zlib.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <map>
#include <memory>
#include <new>
#include <vector>

#include <unistd.h>

#include "core/error.h"

namespace sl {
namespace {

namespace fs = std::filesystem;

constexpr std::size_t kMaxLine = std::size_t(1) << 16;    // a longer line means binary, not a header
constexpr std::size_t kMaxHeader = std::size_t(1) << 24;  // bound the work done on a hostile file
constexpr std::size_t kChunk = std::size_t(1) << 20;      // I/O and zlib buffer size
// zlib counts in 32-bit uInt, so large volumes go through it in pieces of at most this size.
constexpr std::uint64_t kZlibPiece = std::uint64_t(1) << 30;

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};
using File = std::unique_ptr<std::FILE, FileCloser>;

std::string errno_text() { return std::strerror(errno); }

std::string lower(std::string s) {
  for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t");
  if (b == std::string::npos) return {};
  return s.substr(b, s.find_last_not_of(" \t") - b + 1);
}

std::vector<std::string> split_ws(const std::string& s) {
  std::vector<std::string> out;
  std::size_t i = 0;
  while (true) {
    i = s.find_first_not_of(" \t", i);
    if (i == std::string::npos) return out;
    const auto e = s.find_first_of(" \t", i);
    out.push_back(s.substr(i, e == std::string::npos ? std::string::npos : e - i));
    if (e == std::string::npos) return out;
    i = e;
  }
}

// Whole-token parse; from_chars is locale-independent (a decimal comma locale must not break files).
template <class T> bool parse_number(const std::string& s, T& out) {
  const char* b = s.data();
  const char* e = s.data() + s.size();
  if (b != e && *b == '+') ++b;  // from_chars rejects a leading '+', which strtod-based teem accepts
  const auto r = std::from_chars(b, e, out);
  return r.ec == std::errc() && r.ptr == e;
}

// Opens for reading; `who` is the file the error names (the header, for a detached data file), and
// `what` prefixes the reason so the user knows which of the two files is missing.
File open_read(const std::string& path, const std::string& who, const std::string& what) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) throw InputError(who, what + "is a directory, not a file");
  File f(std::fopen(path.c_str(), "rb"));
  if (!f) {
    throw InputError(who, what + (errno == ENOENT ? std::string("file not found")
                                                  : "cannot open: " + errno_text()));
  }
  return f;
}

// Reads one header line without its "\n" (or "\r\n"). Returns false at end of file.
bool read_line(std::FILE* f, std::string& line, const std::string& path) {
  line.clear();
  bool any = false;
  for (int c; (c = std::getc(f)) != EOF;) {
    any = true;
    if (c == '\n') break;
    if (line.size() >= kMaxLine) throw InputError(path, "header line longer than 64 KiB (corrupt header?)");
    line.push_back(char(c));
  }
  if (std::ferror(f)) throw InputError(path, "read error: " + errno_text());
  if (!line.empty() && line.back() == '\r') line.pop_back();
  return any;
}

struct Header {
  VolumeDesc desc;
  bool gzip = false;
  bool big_endian = false;
  std::string data_file;          // resolved path of a detached data file; empty when attached
  std::uint64_t data_offset = 0;  // attached: first byte after the header's blank line
  std::int64_t byte_skip = 0;     // -1: the data are the last bytes of the file (raw only)
  std::int64_t line_skip = 0;
};

VoxelType parse_type(const std::string& path, const std::string& value) {
  std::string v;  // lower case, single spaces: "Unsigned  Short" == "unsigned short"
  for (const auto& w : split_ws(lower(value))) v += (v.empty() ? "" : " ") + w;
  static const std::map<std::string, VoxelType> supported = {
      {"uchar", VoxelType::U8},           {"unsigned char", VoxelType::U8},
      {"uint8", VoxelType::U8},           {"uint8_t", VoxelType::U8},
      {"ushort", VoxelType::U16},         {"unsigned short", VoxelType::U16},
      {"unsigned short int", VoxelType::U16}, {"uint16", VoxelType::U16},
      {"uint16_t", VoxelType::U16},       {"uint", VoxelType::U32},
      {"unsigned int", VoxelType::U32},   {"uint32", VoxelType::U32},
      {"uint32_t", VoxelType::U32},       {"float", VoxelType::F32}};
  if (auto it = supported.find(v); it != supported.end()) return it->second;
  // Valid NRRD types that sparseleap has no voxel type for: say so rather than "unknown".
  static const char* const other[] = {
      "signed char", "int8", "int8_t", "short", "short int", "signed short", "signed short int",
      "int16", "int16_t", "int", "signed int", "int32", "int32_t", "longlong", "long long",
      "long long int", "signed long long", "signed long long int", "int64", "int64_t", "ulonglong",
      "unsigned long long", "unsigned long long int", "uint64", "uint64_t", "double", "block"};
  for (const char* o : other) {
    if (v == o) {
      throw InputError(path, "type '" + value +
                                 "' is not supported (sparseleap reads unsigned char, unsigned short, "
                                 "unsigned int and float)");
    }
  }
  throw InputError(path, "unknown type '" + value + "'");
}

// Lengths of the per-axis vectors of `space directions`, e.g. "(0.5,0,0) (0,0.5,0) none".
std::vector<float> parse_space_directions(const std::string& path, const std::string& value) {
  std::vector<float> lengths;
  std::size_t i = 0;
  const auto bad = [&] { return InputError(path, "cannot parse 'space directions: " + value + "'"); };
  while ((i = value.find_first_not_of(" \t", i)) != std::string::npos) {
    if (value[i] != '(') {
      const auto e = value.find_first_of(" \t", i);
      if (lower(value.substr(i, e - i)) != "none") throw bad();
      lengths.push_back(1.0f);  // non-spatial axis: no physical step known
      i = e;
      continue;
    }
    const auto close = value.find(')', i);
    if (close == std::string::npos) throw bad();
    double sum = 0.0;
    std::string inner = value.substr(i + 1, close - i - 1);
    std::size_t p = 0;
    int components = 0;
    while (true) {
      const auto comma = inner.find(',', p);
      double c = 0.0;
      if (!parse_number(trim(inner.substr(p, comma - p)), c)) throw bad();
      sum += c * c;
      ++components;
      if (comma == std::string::npos) break;
      p = comma + 1;
    }
    if (components < 1 || components > 3) throw bad();
    lengths.push_back(float(std::sqrt(sum)));
    i = close + 1;
  }
  return lengths;
}

Header parse_header(const std::string& path) {
  File f = open_read(path, path, "");
  // Check the magic on raw bytes first, so a binary file is rejected as "not a NRRD" at once.
  char magic[9] = {};
  const std::size_t got = std::fread(magic, 1, 8, f.get());
  if (got < 4 || std::memcmp(magic, "NRRD", 4) != 0) {
    throw InputError(path, "not a NRRD file (it does not start with the magic line 'NRRD000x')");
  }
  std::rewind(f.get());
  std::string line;
  read_line(f.get(), line, path);
  if (line.size() != 8 || line.compare(0, 7, "NRRD000") != 0 || line[7] < '1' || line[7] > '5') {
    throw InputError(path, "unsupported NRRD magic '" + line.substr(0, 16) +
                               "' (expected NRRD0001 to NRRD0005)");
  }

  std::map<std::string, std::string> fields;  // name without spaces, lower case -> value
  bool blank_line = false;
  for (int line_no = 2; read_line(f.get(), line, path); ++line_no) {
    if (std::ftell(f.get()) > long(kMaxHeader)) throw InputError(path, "header larger than 16 MiB");
    if (line.empty()) {  // the blank line ends an attached header; the data follow it
      blank_line = true;
      break;
    }
    if (line[0] == '#') continue;
    const auto colon = line.find(':');
    if (colon == std::string::npos) {
      throw InputError(path, "header line " + std::to_string(line_no) + " ('" + line.substr(0, 60) +
                                 "') is not a 'field: value' pair");
    }
    if (colon + 1 < line.size() && line[colon + 1] == '=') continue;  // key:=value, no geometry
    std::string name;  // "data file" == "datafile", "byte skip" == "byteskip" (both spec spellings)
    for (char c : lower(line.substr(0, colon))) {
      if (c != ' ' && c != '\t') name.push_back(c);
    }
    fields[name] = trim(line.substr(colon + 1));
    // "data file: LIST" is the last field; file names follow, one a line (rejected below).
    if (name == "datafile" && split_ws(fields[name]) == std::vector<std::string>{"LIST"}) break;
  }

  const auto field = [&](const char* name, const char* shown) -> const std::string& {
    const auto it = fields.find(name);
    if (it == fields.end()) throw InputError(path, std::string("missing required field '") + shown + "'");
    return it->second;
  };

  Header h;
  {
    int dim = 0;
    const std::string& v = field("dimension", "dimension");
    if (!parse_number(v, dim)) throw InputError(path, "dimension '" + v + "' is not an integer");
    if (dim != 3) {
      throw InputError(path, "dimension is " + v + "; only 3-D volumes (dimension: 3) are supported");
    }
  }
  h.desc.type = parse_type(path, field("type", "type"));
  {
    const std::string& v = field("sizes", "sizes");
    const auto tok = split_ws(v);
    if (tok.size() != 3) {
      throw InputError(path, "'sizes: " + v + "' has " + std::to_string(tok.size()) +
                                 " values, expected 3 (one per axis)");
    }
    for (int a = 0; a < 3; ++a) {
      std::int64_t s = 0;
      if (!parse_number(tok[a], s)) throw InputError(path, "size '" + tok[a] + "' is not an integer");
      if (s <= 0) {
        throw InputError(path, "size along axis " + std::to_string(a) + " is " + tok[a] +
                                   " (must be positive)");
      }
      if (s > std::numeric_limits<int>::max()) {
        throw InputError(path, "size along axis " + std::to_string(a) + " is " + tok[a] + " (absurdly large)");
      }
      h.desc.dims[a] = int(s);
    }
    // Checked here, not only by validate_desc, so header-only reads also reject impossible sizes.
    std::uint64_t bytes = std::uint64_t(voxel_size(h.desc.type));
    for (int a = 0; a < 3; ++a) {
      if (__builtin_mul_overflow(bytes, std::uint64_t(h.desc.dims[a]), &bytes)) {
        throw InputError(path, "sizes '" + v + "' are absurd: the byte count overflows 64 bits");
      }
    }
  }
  {
    const std::string v = lower(field("encoding", "encoding"));
    if (v == "gzip" || v == "gz") {
      h.gzip = true;
    } else if (v == "txt" || v == "text" || v == "ascii" || v == "hex" || v == "bzip2" || v == "bz2") {
      throw InputError(path, "encoding '" + v + "' is not supported (expected raw or gzip)");
    } else if (v != "raw") {
      throw InputError(path, "unknown encoding '" + v + "' (expected raw or gzip)");
    }
  }
  if (auto it = fields.find("endian"); it != fields.end()) {
    // Optional: teem requires it only for multi-byte types; absent means little (every modern writer).
    const std::string v = lower(it->second);
    if (v != "little" && v != "big") throw InputError(path, "unknown endian '" + v + "' (expected little or big)");
    h.big_endian = v == "big";
  }
  if (auto it = fields.find("spacedirections"); it != fields.end()) {
    // Preferred over `spacings` (the spec forbids both; Slicer writes only this one). Orientation is
    // not modelled: the renderer's world is axis-aligned, so only the step lengths matter.
    const auto len = parse_space_directions(path, it->second);
    if (len.size() != 3) throw InputError(path, "'space directions' must have 3 entries, one per axis");
    h.desc.spacing = vec3(len[0], len[1], len[2]);
  } else if (auto it2 = fields.find("spacings"); it2 != fields.end()) {
    const auto tok = split_ws(it2->second);
    if (tok.size() != 3) throw InputError(path, "'spacings' must have 3 values, one per axis");
    for (int a = 0; a < 3; ++a) {
      double s = 0.0;
      if (!parse_number(tok[a], s)) throw InputError(path, "spacing '" + tok[a] + "' is not a number");
      // NaN marks an axis without a known spacing; a negative one only flips the axis direction.
      h.desc.spacing[a] = std::isnan(s) ? 1.0f : float(std::fabs(s));
    }
  }
  for (const char* name : {"byteskip", "lineskip"}) {
    const auto it = fields.find(name);
    if (it == fields.end()) continue;
    std::int64_t n = 0;
    const bool bytes = name[0] == 'b';
    if (!parse_number(it->second, n) || n < (bytes ? -1 : 0)) {
      throw InputError(path, std::string(bytes ? "byte" : "line") + " skip '" + it->second + "' is invalid");
    }
    (bytes ? h.byte_skip : h.line_skip) = n;
  }
  if (h.byte_skip == -1 && h.gzip) throw InputError(path, "'byte skip: -1' is only allowed with raw encoding");

  if (auto it = fields.find("datafile"); it != fields.end()) {
    const std::string& v = it->second;
    const auto tok = split_ws(v);
    if (v.empty()) throw InputError(path, "'data file' is empty");
    // Multi-file forms: "LIST" (names on the following lines) or "fmt%d min max step [subdim]".
    if (tok[0] == "LIST" || (tok.size() >= 4 && tok[0].find('%') != std::string::npos)) {
      throw InputError(path, "multi-file data ('data file: " + v + "') are not supported");
    }
    fs::path p(v);
    if (p.is_relative()) p = fs::path(path).parent_path() / p;  // relative to the header's directory
    h.data_file = p.string();
  } else if (!blank_line) {
    throw InputError(path, "header has no blank line followed by data and no 'data file' field");
  }
  h.data_offset = std::uint64_t(ftello(f.get()));
  return h;
}

void swap_bytes(std::byte* p, std::uint64_t count, int size) {
  for (std::uint64_t i = 0; i < count; ++i, p += size) std::reverse(p, p + size);
}

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

VolumeDesc read_nrrd_header(const std::string& path) {
  Header h = parse_header(path);
  validate_desc(h.desc, path, std::numeric_limits<std::uint64_t>::max());  // overflow only
  return h.desc;
}

Volume read_nrrd(const std::string& path) {
  const Header h = parse_header(path);
  validate_desc(h.desc, path);
  const bool detached = !h.data_file.empty();
  const std::string where = detached ? "data file '" + h.data_file + "': " : "";
  File f = open_read(detached ? h.data_file : path, path, where);
  if (!detached && fseeko(f.get(), off_t(h.data_offset), SEEK_SET) != 0) {
    throw InputError(path, "cannot seek: " + errno_text());
  }
  for (std::int64_t i = 0; i < h.line_skip; ++i) {
    int c;
    while ((c = std::getc(f.get())) != EOF && c != '\n') {
    }
    if (c == EOF) throw InputError(path, where + "data truncated: file ends within the skipped lines");
  }

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

// A file written under a hidden temporary name beside its destination and renamed into place by
// publish(); destroyed unpublished, it removes itself. Errors name `who` (the path the user gave).
class TempFile {
 public:
  TempFile(const fs::path& final_path, std::string who) : final_(final_path), who_(std::move(who)) {
    static std::atomic<unsigned> counter{0};
    const fs::path dir = final_.has_parent_path() ? final_.parent_path() : fs::path(".");
    // Hidden and suffixed: never mistaken for the finished file. (Built with append: GCC 12 warns
    // falsely, -Wrestrict, on `"." + std::string`.)
    std::string name(1, '.');
    name.append(final_.filename().string()).append(".part-").append(std::to_string(::getpid()));
    name.append("-").append(std::to_string(counter++));
    tmp_ = dir / name;
    f_.reset(std::fopen(tmp_.c_str(), "wb"));
    if (!f_) throw InputError(who_, "cannot write '" + final_.string() + "': " + errno_text());
  }
  TempFile(const TempFile&) = delete;
  TempFile& operator=(const TempFile&) = delete;
  ~TempFile() {
    f_.reset();
    if (!published_) {
      std::error_code ec;
      fs::remove(tmp_, ec);
    }
  }

  void write(const void* p, std::size_t n) {
    if (n && std::fwrite(p, 1, n, f_.get()) != n) fail();
  }
  // Flushes and closes, so errors such as a full disk surface before anything is renamed.
  void finish() {
    if (std::fclose(f_.release()) != 0) fail();
  }
  const fs::path& path() const { return final_; }
  void publish() {
    std::error_code ec;
    fs::rename(tmp_, final_, ec);
    if (ec) throw InputError(who_, "cannot write '" + final_.string() + "': " + ec.message());
    published_ = true;
  }

 private:
  [[noreturn]] void fail() {
    throw InputError(who_, "writing '" + final_.string() + "' failed: " + errno_text());
  }
  fs::path final_, tmp_;
  std::string who_;
  File f_;
  bool published_ = false;
};

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

void write_payload(TempFile& out, const Volume& v, bool gzip) {
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

void write_nrrd(const std::string& path, const Volume& v, bool gzip) {
  const fs::path out(path);
  const std::string ext = lower(out.extension().string());
  if (ext != ".nrrd" && ext != ".nhdr") {
    throw InputError(path, "output name must end in .nrrd (attached) or .nhdr (detached header)");
  }
  if (v.empty()) throw InputError(path, "cannot write an empty volume");
  const VolumeDesc& d = v.desc();
  const bool detached = ext == ".nhdr";
  const std::string data_name = out.stem().string() + (gzip ? ".raw.gz" : ".raw");

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

  TempFile head(out, path);
  head.write(header.data(), header.size());
  if (!detached) {
    write_payload(head, v, gzip);
    head.finish();
    head.publish();
    return;
  }
  TempFile data(out.has_parent_path() ? out.parent_path() / data_name : fs::path(data_name), path);
  write_payload(data, v, gzip);
  data.finish();
  head.finish();
  // Data first: the header is what makes the pair look complete, so it appears last.
  data.publish();
  try {
    head.publish();
  } catch (...) {
    std::error_code ec;  // a data file without its header is debris: remove what we just wrote
    fs::remove(data.path(), ec);
    throw;
  }
}

}  // namespace sl
