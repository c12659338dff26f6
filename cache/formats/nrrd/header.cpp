#include "cache/formats/nrrd/header.h"

#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <map>
#include <vector>

#include <unistd.h>

#include "cache/formats/nrrd/nrrd.h"
#include "core/util/error.h"
#include "core/util/input_file.h"

namespace sl {
namespace nrrd_detail {
namespace {

namespace fs = std::filesystem;

constexpr std::size_t kMaxLine = std::size_t(1) << 16;    // a longer line means binary, not a header
constexpr std::size_t kMaxHeader = std::size_t(1) << 24;  // bound the work done on a hostile file

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

using Fields = std::map<std::string, std::string>;  // name without spaces, lower case -> value

// Checks the magic line; leaves `f` after it.
void read_magic(std::FILE* f, const std::string& path) {
  // Check the magic on raw bytes first, so a binary file is rejected as "not a NRRD" at once.
  char magic[9] = {};
  const std::size_t got = std::fread(magic, 1, 8, f);
  if (got < 4 || std::memcmp(magic, "NRRD", 4) != 0) {
    throw InputError(path, "not a NRRD file (it does not start with the magic line 'NRRD000x')");
  }
  std::rewind(f);
  std::string line;
  read_line(f, line, path);
  if (line.size() != 8 || line.compare(0, 7, "NRRD000") != 0 || line[7] < '1' || line[7] > '5') {
    throw InputError(path, "unsupported NRRD magic '" + line.substr(0, 16) +
                               "' (expected NRRD0001 to NRRD0005)");
  }
}

// Reads the field lines up to the blank line that ends an attached header (true: seen; `f` is then at
// the data) or the end of a detached one.
bool read_fields(std::FILE* f, const std::string& path, Fields& fields) {
  std::string line;
  for (int line_no = 2; read_line(f, line, path); ++line_no) {
    if (std::ftell(f) > long(kMaxHeader)) throw InputError(path, "header larger than 16 MiB");
    if (line.empty()) return true;
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
    if (name == "datafile") {
      const auto tok = split_ws(fields[name]);
      if (!tok.empty() && tok[0] == "LIST") break;
    }
  }
  return false;
}

const std::string& required(const Fields& fields, const std::string& path, const char* name) {
  const auto it = fields.find(name);
  if (it == fields.end()) throw InputError(path, std::string("missing required field '") + name + "'");
  return it->second;
}

void check_dimension(const Fields& fields, const std::string& path) {
  int dim = 0;
  const std::string& v = required(fields, path, "dimension");
  if (!parse_number(v, dim)) throw InputError(path, "dimension '" + v + "' is not an integer");
  if (dim != 3) {
    throw InputError(path, "dimension is " + v + "; only 3-D volumes (dimension: 3) are supported");
  }
}

// The dims; needs the type, to check the byte count.
void parse_sizes(const Fields& fields, const std::string& path, Header& h) {
  const std::string& v = required(fields, path, "sizes");
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

void parse_encoding(const Fields& fields, const std::string& path, Header& h) {
  const std::string v = lower(required(fields, path, "encoding"));
  if (v == "gzip" || v == "gz") {
    h.gzip = true;
  } else if (v == "txt" || v == "text" || v == "ascii" || v == "hex" || v == "bzip2" || v == "bz2") {
    throw InputError(path, "encoding '" + v + "' is not supported (expected raw or gzip)");
  } else if (v != "raw") {
    throw InputError(path, "unknown encoding '" + v + "' (expected raw or gzip)");
  }
}

void parse_endian(const Fields& fields, const std::string& path, Header& h) {
  // Optional: teem requires it only for multi-byte types; absent means little (every modern writer).
  const auto it = fields.find("endian");
  if (it == fields.end()) return;
  const std::string v = lower(it->second);
  if (v != "little" && v != "big") throw InputError(path, "unknown endian '" + v + "' (expected little or big)");
  h.big_endian = v == "big";
}

void parse_spacing(const Fields& fields, const std::string& path, Header& h) {
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
      // Refused rather than guessed: NaN (unknown) would silently become 1 and a negative spacing (a
      // flipped axis, which the axis-aligned world cannot show) would silently lose its sign. Zero is
      // refused by validate_desc, naming the axis.
      if (std::isnan(s) || s < 0.0) throw InputError(path, "spacing '" + tok[a] + "' must be a positive number");
      h.desc.spacing[a] = float(s);
    }
  }
}

// `byte skip` and `line skip`; needs the encoding (a skip of -1 is raw only).
void parse_skips(const Fields& fields, const std::string& path, Header& h) {
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
}

// Where the data are: a detached `data file`, or after the blank line of an attached header.
void parse_data_file(const Fields& fields, const std::string& path, bool blank_line, Header& h) {
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
}

}  // namespace

std::string errno_text() { return std::strerror(errno); }

std::string lower(std::string s) {
  for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

File open_read(const std::string& path, const std::string& who, const std::string& what) {
  // Without blocking, and only a regular file (input_file.h): a FIFO would wait for a writer forever.
  int fd = -1;
  try {
    fd = open_input_fd(path);
  } catch (const InputError& e) {
    throw InputError(who, what + (who == path ? e.reason() : e.what()));
  }
  if (fd < 0) throw InputError(who, what + "file not found");
  File f(::fdopen(fd, "rb"));
  if (!f) {
    ::close(fd);
    throw InputError(who, what + "cannot open: " + errno_text());
  }
  return f;
}

Header parse_header(const std::string& path) {
  File f = open_read(path, path, "");
  read_magic(f.get(), path);
  Fields fields;
  const bool blank_line = read_fields(f.get(), path, fields);
  Header h;
  check_dimension(fields, path);
  h.desc.type = parse_type(path, required(fields, path, "type"));
  parse_sizes(fields, path, h);
  parse_encoding(fields, path, h);
  parse_endian(fields, path, h);
  parse_spacing(fields, path, h);
  parse_skips(fields, path, h);
  parse_data_file(fields, path, blank_line, h);
  h.data_offset = std::uint64_t(ftello(f.get()));
  return h;
}

}  // namespace nrrd_detail

VolumeDesc read_nrrd_header(const std::string& path) {
  const nrrd_detail::Header h = nrrd_detail::parse_header(path);
  validate_desc(h.desc, path, std::numeric_limits<std::uint64_t>::max());  // spacing; no memory limit
  return h.desc;
}

}  // namespace sl
