// The bad-input corpus (issue 15): well over a hundred broken inputs across NRRD, NIfTI, TIFF, OME-Zarr,
// transfer-function / camera / camera-path JSON, command-line values and output paths, each made by
// this test from our own writers (or a few lines of header bytes) plus a byte edit, and each run as a
// user or a script would run it. Every case must end with the expected exit status (1 bad input or
// data, 2 command-line syntax), exactly one line on stderr that names the file or option and the
// problem (no raw control bytes), no signal and no sanitizer report, within a timeout, and leave its
// working folder exactly as it was (no output, no temporary, nothing replaced).
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "cache/formats/nrrd.h"
#include "cache/synthetic/generate.h"
#include "core/volume.h"
#include "tests/test_util.h"

namespace sl {
namespace {

namespace fs = std::filesystem;

using Bytes = std::string;

Bytes read_bytes(const fs::path& p) { return test::read_text(p); }
void write_bytes(const fs::path& p, const Bytes& b) { test::write_text(p, b); }

// Replaces the first `from` in `b` (it must be there: a case that edits nothing tests nothing).
Bytes replaced(Bytes b, const std::string& from, const std::string& to) {
  const auto pos = b.find(from);
  if (pos == std::string::npos) throw std::runtime_error("case setup: '" + from + "' not found");
  return b.replace(pos, from.size(), to);
}
void edit(const fs::path& p, const std::string& from, const std::string& to) {
  write_bytes(p, replaced(read_bytes(p), from, to));
}
void truncate_to(const fs::path& p, std::size_t n) { fs::resize_file(p, n); }

template <class T> void poke(Bytes& b, std::size_t offset, T v) { std::memcpy(b.data() + offset, &v, sizeof v); }

// ---- Inputs made from our own writers ----------------------------------------------------------

// A NIfTI-1 single file (.nii): the 348-byte header, the 4-byte extension flag, the voxels.
Bytes nifti_bytes(int nx, int ny, int nz, std::int16_t datatype, std::int16_t bitpix) {
  Bytes b(352, '\0');
  poke<std::int32_t>(b, 0, 348);
  const std::int16_t dim[8] = {3, std::int16_t(nx), std::int16_t(ny), std::int16_t(nz), 1, 1, 1, 1};
  for (int i = 0; i < 8; ++i) poke<std::int16_t>(b, 40 + 2 * std::size_t(i), dim[i]);
  poke<std::int16_t>(b, 70, datatype);
  poke<std::int16_t>(b, 72, bitpix);
  for (int i = 0; i < 4; ++i) poke<float>(b, 76 + 4 * std::size_t(i), 1.0f);
  poke<float>(b, 108, 352.0f);
  std::memcpy(b.data() + 344, "n+1", 4);
  Bytes data(std::size_t(nx) * std::size_t(ny) * std::size_t(nz) * std::size_t(bitpix / 8), '\0');
  for (std::size_t i = 0; i < data.size(); ++i) data[i] = char(i * 7);
  return b + data;
}

// A baseline little-endian TIFF, one strip per page.
struct TiffPage {
  std::uint32_t w = 8, h = 8;
  std::uint16_t bits = 8, spp = 1, compression = 1, sample_format = 1;
  std::int64_t strip_offset = -1;  // -1: where the data are
  std::int64_t strip_bytes = -1;   // -1: the data's size
};
Bytes tiff_bytes(const std::vector<TiffPage>& pages) {
  Bytes b("II*\0\x08\0\0\0", 8);
  constexpr int kEntries = 10;
  for (std::size_t k = 0; k < pages.size(); ++k) {
    const TiffPage& p = pages[k];
    const std::size_t ifd = b.size(), data_at = ifd + 2 + 12 * kEntries + 4;
    // An absurd page keeps its header sizes but carries no data (the reader must refuse it first).
    const std::size_t voxels = std::size_t(p.w) * p.h * p.spp;
    const std::size_t data_size = voxels > (1u << 20) ? 0 : voxels * std::max<std::uint16_t>(p.bits / 8, 1);
    Bytes e(2 + 12 * kEntries + 4, '\0');
    poke<std::uint16_t>(e, 0, kEntries);
    int n = 0;
    const auto entry = [&](std::uint16_t tag, std::uint16_t type, std::uint32_t value) {
      const std::size_t o = 2 + 12 * std::size_t(n++);
      poke<std::uint16_t>(e, o, tag);
      poke<std::uint16_t>(e, o + 2, type);
      poke<std::uint32_t>(e, o + 4, 1);
      if (type == 3) {
        poke<std::uint16_t>(e, o + 8, std::uint16_t(value));
      } else {
        poke<std::uint32_t>(e, o + 8, value);
      }
    };
    entry(256, 4, p.w);
    entry(257, 4, p.h);
    entry(258, 3, p.bits);
    entry(259, 3, p.compression);
    entry(262, 3, 1);
    entry(273, 4, std::uint32_t(p.strip_offset < 0 ? std::int64_t(data_at) : p.strip_offset));
    entry(277, 3, p.spp);
    entry(278, 4, p.h);
    entry(279, 4, std::uint32_t(p.strip_bytes < 0 ? std::int64_t(data_size) : p.strip_bytes));
    entry(339, 3, p.sample_format);
    const bool last = k + 1 == pages.size();
    poke<std::uint32_t>(e, 2 + 12 * kEntries, last ? 0u : std::uint32_t(data_at + data_size));
    b += e;
    for (std::size_t i = 0; i < data_size; ++i) b.push_back(char(i * 3));
  }
  return b;
}

struct Templates {
  fs::path dir;
  Bytes nrrd, nrrd_gz, labels16, labels_f32, nhdr;  // attached u8 16³, gzip, its u16 labels, f32, detached
  Bytes nhdr_raw;
  fs::path store, store_raw;  // OME-Zarr with labels (blosc-zstd; uncompressed)
  std::uint64_t phys_bytes = 0;
};
Templates* g_templates = nullptr;

const std::string kTf = R"({"points":[{"value":0,"rgba":[0,0,0,0]},{"value":255,"rgba":[1,1,1,1]}]})";
const std::string kCam = R"({"eye":[40,40,40],"center":[8,8,8],"up":[0,0,1],"fov_deg":30})";
const std::string kPath = R"({"frames":3,"keyframes":[{"eye":[40,40,40],"center":[8,8,8],"up":[0,0,1],"fov_deg":30},)"
                          R"({"eye":[-40,40,40],"center":[8,8,8],"up":[0,0,1],"fov_deg":30}]})";

// ---- The corpus ----------------------------------------------------------------------------------

struct Case {
  std::string format;  // nrrd, nifti, tiff, zarr, json, cli, output
  std::string name;
  std::function<void(const fs::path&)> make;  // writes the case's inputs into its (empty) folder
  std::string args;    // run in that folder
  int exit = 1;        // 1 bad input or data, 2 syntax
  std::string needle;  // in the error line: the file or option and the problem
};

using Make = std::function<void(const fs::path&)>;
const Make kNothing = [](const fs::path&) {};
Make file(const std::string& name, const Bytes& bytes) {
  return [=](const fs::path& d) { write_bytes(d / name, bytes); };
}
Make both(Make a, Make b) {
  return [=](const fs::path& d) { a(d); b(d); };
}
Make store(const std::string& name, std::function<void(const fs::path&)> edit_fn, bool raw = false) {
  return [=](const fs::path& d) {
    fs::copy(raw ? g_templates->store_raw : g_templates->store, d / name, fs::copy_options::recursive);
    edit_fn(d / name);
  };
}
// The first chunk file of an array folder (sorted, so the same one every run).
fs::path first_chunk(const fs::path& array) {
  std::vector<fs::path> chunks;
  for (const auto& e : fs::recursive_directory_iterator(array)) {
    if (e.is_regular_file() && e.path().filename().string()[0] != '.') chunks.push_back(e.path());
  }
  std::sort(chunks.begin(), chunks.end());
  if (chunks.empty()) throw std::runtime_error("case setup: no chunk in " + array.string());
  return chunks.front();
}
// A "full" device (what /dev/full is) in the case's folder: as root a device node of its own, so that a
// bug that replaced it could not destroy the machine's /dev/full; otherwise a symlink to /dev/full
// (which nobody but root can replace).
Make full_device(const std::string& name) {
  return [=](const fs::path& d) {
    if (::geteuid() == 0) {
      ASSERT_EQ(::mknod((d / name).c_str(), S_IFCHR | 0666, ::makedev(1, 7)), 0) << std::strerror(errno);
    } else {
      fs::create_symlink("/dev/full", d / name);
    }
  };
}
std::string nest(int depth) { return std::string(std::size_t(depth), '[') + std::string(std::size_t(depth), ']'); }

const std::string kRender = "render --backend cpu --size 8x8 --out out ";
const std::string kRenderSmall = kRender + "--volume builtin:neurites:16x16x16 ";

std::vector<Case> nrrd_cases() {
  const Templates& t = *g_templates;
  const std::string head = t.nrrd.substr(0, t.nrrd.find("\n\n") + 2);
  const Bytes data = t.nrrd.substr(head.size());
  const auto with_header = [&](const std::string& from, const std::string& to) {
    return file("v.nrrd", replaced(head, from, to) + data);
  };
  const std::string r = kRender + "--volume v.nrrd";
  std::vector<Case> c = {
      {"nrrd", "empty file", file("v.nrrd", ""), r, 1, "v.nrrd: "},
      {"nrrd", "bad magic", file("v.nrrd", replaced(t.nrrd, "NRRD0004", "NRRX0004")), r, 1, "v.nrrd: "},
      {"nrrd", "header without end", file("v.nrrd", head.substr(0, head.size() - 2)), r, 1, "v.nrrd: "},
      {"nrrd", "data truncated", file("v.nrrd", t.nrrd.substr(0, t.nrrd.size() - 100)), r, 1, "v.nrrd: "},
      {"nrrd", "header only", file("v.nrrd", head), r, 1, "v.nrrd: "},
      {"nrrd", "unknown type", with_header("unsigned char", "complex"), r, 1, "v.nrrd: "},
      {"nrrd", "signed type", with_header("unsigned char", "signed char"), r, 1, "v.nrrd: "},
      {"nrrd", "double type", with_header("unsigned char", "double"), r, 1, "v.nrrd: "},
      {"nrrd", "no type", with_header("type: unsigned char\n", ""), r, 1, "v.nrrd: "},
      {"nrrd", "dimension 2", with_header("dimension: 3", "dimension: 2"), r, 1, "v.nrrd: "},
      {"nrrd", "dimension 9", with_header("dimension: 3", "dimension: 9"), r, 1, "v.nrrd: "},
      {"nrrd", "size zero", with_header("sizes: 16 16 16", "sizes: 0 16 16"), r, 1, "v.nrrd: "},
      {"nrrd", "size negative", with_header("sizes: 16 16 16", "sizes: 16 -16 16"), r, 1, "v.nrrd: "},
      {"nrrd", "size overflows", with_header("sizes: 16 16 16", "sizes: 16 99999999999999999999 16"), r, 1, "v.nrrd: "},
      {"nrrd", "size not a number", with_header("sizes: 16 16 16", "sizes: 16 sixteen 16"), r, 1, "v.nrrd: "},
      {"nrrd", "two sizes", with_header("sizes: 16 16 16", "sizes: 16 16"), r, 1, "v.nrrd: "},
      {"nrrd", "absurd dims", with_header("sizes: 16 16 16", "sizes: 4000000 4000000 4000000"), r, 1, "v.nrrd: "},
      {"nrrd", "bzip2 encoding", with_header("encoding: raw", "encoding: bzip2"), r, 1, "v.nrrd: "},
      {"nrrd", "gzip encoding of raw data", with_header("encoding: raw", "encoding: gzip"), r, 1, "v.nrrd: "},
      {"nrrd", "gzip data truncated", file("v.nrrd", t.nrrd_gz.substr(0, t.nrrd_gz.size() * 2 / 3)), r, 1, "v.nrrd: "},
      {"nrrd", "gzip data flipped",
       file("v.nrrd", t.nrrd_gz.substr(0, t.nrrd_gz.size() - 40) + Bytes(40, '\x5a')), r, 1, "v.nrrd: "},
      {"nrrd", "middle endian", with_header("endian: little", "endian: middle"), r, 1, "v.nrrd: "},
      {"nrrd", "NaN spacing", with_header("spacings: 1 1 1", "spacings: nan 1 1"), r, 1, "v.nrrd: spacing"},
      {"nrrd", "negative spacing", with_header("spacings: 1 1 1", "spacings: 1 -2 1"), r, 1, "v.nrrd: spacing"},
      {"nrrd", "infinite spacing", with_header("spacings: 1 1 1", "spacings: 1 1 inf"), r, 1, "v.nrrd: "},
      {"nrrd", "zero spacing", with_header("spacings: 1 1 1", "spacings: 0 1 1"), r, 1, "v.nrrd: "},
      {"nrrd", "byte skip past the end", with_header("encoding: raw\n", "encoding: raw\nbyte skip: 100000\n"), r, 1,
       "v.nrrd: "},
      {"nrrd", "control byte in the type", with_header("unsigned char", "unsigned\x07" "char"), r, 1,
       "v.nrrd: "},
      {"nrrd", "control bytes in the encoding", with_header("encoding: raw", "encoding: r\x1b[2Jaw\x7f"), r, 1,
       "v.nrrd: "},
      {"nrrd", "detached data missing", file("v.nhdr", t.nhdr), kRender + "--volume v.nhdr", 1, "v.raw"},
      {"nrrd", "detached data short", both(file("v.nhdr", t.nhdr), file("v.raw", t.nhdr_raw.substr(0, 100))),
       kRender + "--volume v.nhdr", 1, "v.nhdr: "},
      {"nrrd", "detached data is a directory",
       [](const fs::path& d) { write_bytes(d / "v.nhdr", g_templates->nhdr); fs::create_directory(d / "v.raw"); },
       kRender + "--volume v.nhdr", 1, "v.raw"},
      {"nrrd", "labels of float type", both(file("v.nrrd", t.nrrd), file("l.nrrd", t.labels_f32)),
       r + " --labels l.nrrd", 1, "l.nrrd: "},
      {"nrrd", "labels of other dims",
       both(file("v.nrrd", t.nrrd), file("l.nrrd", replaced(t.labels16, "sizes: 16 16 16", "sizes: 16 16 8").substr(
                                                       0, t.labels16.size() - 16 * 16 * 8 * 2))),
       r + " --labels l.nrrd", 1, "l.nrrd: "},
      {"nrrd", "label id 0xFFFFFFFF", [](const fs::path& d) {
         write_bytes(d / "v.nrrd", g_templates->nrrd);
         Volume lab(VolumeDesc{{16, 16, 16}, vec3(1.0f), VoxelType::U32});
         lab.as<std::uint32_t>()[100] = 0xFFFFFFFFu;
         write_nrrd((d / "l.nrrd").string(), lab);
       }, r + " --labels l.nrrd --mode labels", 1, "l.nrrd: largest label id 4294967295"},
      {"nrrd", "a device as the volume", kNothing, kRender + "--volume /dev/zero", 1, "/dev/zero: not a NRRD file"},
      {"nrrd", "a device as the data file", file("v.nhdr", replaced(t.nhdr, "data file: v.raw", "data file: /dev/zero")),
       kRender + "--volume v.nhdr", 1, "v.nhdr: data file '/dev/zero'"},
      {"nrrd", "info of a truncated file", file("v.nrrd", head.substr(0, 20)), "info v.nrrd", 1, "v.nrrd: "},
      {"nrrd", "info --stats of truncated data", file("v.nrrd", t.nrrd.substr(0, t.nrrd.size() - 1)),
       "info --stats v.nrrd", 1, "v.nrrd: "},
      {"nrrd", "ingest of truncated data", file("v.nrrd", t.nrrd.substr(0, t.nrrd.size() - 1)),
       "ingest v.nrrd s.zarr", 1, "v.nrrd: "},
      {"nrrd", "bench of a bad file", file("v.nrrd", "NRRD0004\n\n"), "bench --size 8x8 --orbit 1 --volume v.nrrd", 1,
       "v.nrrd: "},
  };
  // Dims that fit the format but not this machine: refused from the header, never allocated.
  const std::uint64_t side = 4096, z = t.phys_bytes / (side * side) + 1;
  // Ingest streams, but holds a layer of chunk x X x Y voxels per level: 100000² slices cannot fit.
  c.push_back({"nrrd", "ingest layers larger than memory", [](const fs::path& d) {
                 const std::string h = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 100000 100000 2\nencoding: raw\n\n";
                 write_bytes(d / "v.nrrd", h);
                 fs::resize_file(d / "v.nrrd", h.size() + 20000000000ull);  // sparse: no disk used
               },
               "ingest v.nrrd s.zarr", 1, "v.nrrd: ingest would need"});
  c.push_back({"nrrd", "more voxels than memory",
               with_header("sizes: 16 16 16", "sizes: 4096 4096 " + std::to_string(z)), r, 1,
               "v.nrrd: 4096x4096x" + std::to_string(z) + " u8 needs"});
  return c;
}

std::vector<Case> nifti_cases() {
  const Bytes good = nifti_bytes(8, 8, 8, 2, 8);
  const auto edited = [&](auto fn) {
    Bytes b = good;
    fn(b);
    return file("v.nii", b);
  };
  const std::string r = kRender + "--volume v.nii";
  return {
      {"nifti", "empty file", file("v.nii", ""), r, 1, "v.nii: "},
      {"nifti", "shorter than a header", file("v.nii", good.substr(0, 100)), r, 1, "v.nii: "},
      {"nifti", "sizeof_hdr wrong", edited([](Bytes& b) { poke<std::int32_t>(b, 0, 349); }), r, 1, "v.nii: "},
      {"nifti", "NIfTI-2", edited([](Bytes& b) { poke<std::int32_t>(b, 0, 540); }), r, 1, "v.nii: NIfTI-2"},
      {"nifti", "bad magic", edited([](Bytes& b) { std::memcpy(b.data() + 344, "xyz", 4); }), r, 1, "v.nii: "},
      {"nifti", "control bytes in magic", edited([](Bytes& b) { std::memcpy(b.data() + 344, "\x07\x08\x1b", 4); }),
       r, 1, "v.nii: "},
      {"nifti", "hdr/img pair", edited([](Bytes& b) { std::memcpy(b.data() + 344, "ni1", 4); }), r, 1, "v.nii: "},
      {"nifti", "dim[0] zero", edited([](Bytes& b) { poke<std::int16_t>(b, 40, 0); }), r, 1, "v.nii: "},
      {"nifti", "dim[0] eight", edited([](Bytes& b) { poke<std::int16_t>(b, 40, 8); }), r, 1, "v.nii: "},
      {"nifti", "dim[1] zero", edited([](Bytes& b) { poke<std::int16_t>(b, 42, 0); }), r, 1, "v.nii: "},
      {"nifti", "dim[2] negative", edited([](Bytes& b) { poke<std::int16_t>(b, 44, -5); }), r, 1, "v.nii: "},
      {"nifti", "time series", edited([](Bytes& b) { poke<std::int16_t>(b, 40, 4); poke<std::int16_t>(b, 48, 3); }),
       r, 1, "v.nii: "},
      {"nifti", "float64", edited([](Bytes& b) { poke<std::int16_t>(b, 70, 64); }), r, 1, "v.nii: "},
      {"nifti", "datatype 0", edited([](Bytes& b) { poke<std::int16_t>(b, 70, 0); }), r, 1, "v.nii: "},
      {"nifti", "vox_offset zero", edited([](Bytes& b) { poke<float>(b, 108, 0.0f); }), r, 1, "v.nii: "},
      {"nifti", "vox_offset NaN", edited([](Bytes& b) { poke<float>(b, 108, NAN); }), r, 1, "v.nii: "},
      {"nifti", "vox_offset huge", edited([](Bytes& b) { poke<float>(b, 108, 1e12f); }), r, 1, "v.nii: "},
      {"nifti", "vox_offset past the end", edited([](Bytes& b) { poke<float>(b, 108, 100000.0f); }), r, 1, "v.nii: "},
      {"nifti", "data truncated", file("v.nii", good.substr(0, good.size() - 1)), r, 1, "v.nii: "},
      {"nifti", "absurd dims", edited([](Bytes& b) {
         for (int i = 1; i <= 3; ++i) poke<std::int16_t>(b, 40 + 2 * std::size_t(i), 32767);
         poke<std::int16_t>(b, 70, 16);
         poke<std::int16_t>(b, 72, 32);
       }), r, 1, "v.nii: "},
      {"nifti", "gzip corrupt", file("v.nii.gz", Bytes("\x1f\x8b\x08\x00\0\0\0\0\0\x03", 10) + Bytes(500, '\x33')),
       kRender + "--volume v.nii.gz", 1, "v.nii.gz: "},
      {"nifti", "gzip truncated", [good](const fs::path& d) {
         write_bytes(d / "g.nii", good + Bytes(4000, '\x11'));
         ASSERT_EQ(std::system(("gzip -n -c " + (d / "g.nii").string() + " > " + (d / "v.nii.gz").string()).c_str()), 0);
         fs::remove(d / "g.nii");
         truncate_to(d / "v.nii.gz", fs::file_size(d / "v.nii.gz") / 2);
       }, kRender + "--volume v.nii.gz", 1, "v.nii.gz: "},
      {"nifti", "ingest of truncated data", file("v.nii", good.substr(0, good.size() - 10)), "ingest v.nii s.zarr", 1,
       "v.nii: "},
      {"nifti", "info of a bad header", edited([](Bytes& b) { poke<std::int16_t>(b, 42, 0); }), "info v.nii", 1,
       "v.nii: "},
  };
}

std::vector<Case> tiff_cases() {
  const auto one = [](TiffPage p) { return file("v.tif", tiff_bytes({p})); };
  const Bytes good = tiff_bytes({TiffPage{}, TiffPage{}, TiffPage{}});
  const std::string r = kRender + "--volume v.tif";
  return {
      {"tiff", "empty file", file("v.tif", ""), r, 1, "v.tif"},
      {"tiff", "bad magic", file("v.tif", replaced(good, "II*", "IJ*")), r, 1, "v.tif"},
      {"tiff", "header only", file("v.tif", good.substr(0, 8)), r, 1, "v.tif"},
      {"tiff", "truncated in the first directory", file("v.tif", good.substr(0, 40)), r, 1, "v.tif"},
      {"tiff", "directory offset past the end", file("v.tif", replaced(good, Bytes("II*\0\x08", 5), Bytes("II*\0\xf0", 5))),
       r, 1, "v.tif"},
      {"tiff", "data truncated", file("v.tif", good.substr(0, good.size() - 10)), r, 1, "v.tif"},
      {"tiff", "zero width", one(TiffPage{.w = 0}), r, 1, "v.tif"},
      {"tiff", "12 bits", one(TiffPage{.bits = 12}), r, 1, "v.tif"},
      {"tiff", "RGB", one(TiffPage{.spp = 3}), r, 1, "v.tif"},
      {"tiff", "signed samples", one(TiffPage{.bits = 16, .sample_format = 2}), r, 1, "v.tif"},
      {"tiff", "16-bit float", one(TiffPage{.bits = 16, .sample_format = 3}), r, 1, "v.tif"},
      {"tiff", "unknown compression", one(TiffPage{.compression = 34712}), r, 1, "v.tif"},
      {"tiff", "strip offset past the end", one(TiffPage{.strip_offset = 1 << 20}), r, 1, "v.tif"},
      {"tiff", "directory chain loops", [](const fs::path& d) {
         Bytes b = tiff_bytes({TiffPage{}, TiffPage{}});
         poke<std::uint32_t>(b, 8 + 2 + 12 * 10 + 8 * 8 + 2 + 12 * 10, 8);  // page 2's next IFD: page 1
         write_bytes(d / "v.tif", b);
       }, r, 1, "v.tif"},
      {"tiff", "pages of different sizes", file("v.tif", tiff_bytes({TiffPage{}, TiffPage{.w = 9}})), r, 1, "v.tif"},
      {"tiff", "absurd size", one(TiffPage{.w = 0x7fffffff, .h = 0x7fffffff}), r, 1, "v.tif"},
      {"tiff", "slices of different sizes",
       [](const fs::path& d) {
         fs::create_directory(d / "s");
         write_bytes(d / "s" / "a.tif", tiff_bytes({TiffPage{}}));
         write_bytes(d / "s" / "b.tif", tiff_bytes({TiffPage{.w = 6}}));
       }, kRender + "--volume s", 1, "b.tif"},
      {"tiff", "slices of different types",
       [](const fs::path& d) {
         fs::create_directory(d / "s");
         write_bytes(d / "s" / "a.tif", tiff_bytes({TiffPage{}}));
         write_bytes(d / "s" / "b.tif", tiff_bytes({TiffPage{.bits = 16}}));
       }, kRender + "--volume s", 1, "b.tif"},
      {"tiff", "folder without slices", [](const fs::path& d) { fs::create_directory(d / "s"); }, kRender + "--volume s",
       1, "s: "},
      {"tiff", "a slice that is not a TIFF",
       [](const fs::path& d) {
         fs::create_directory(d / "s");
         write_bytes(d / "s" / "a.tif", tiff_bytes({TiffPage{}}));
         write_bytes(d / "s" / "b.tif", "not a tiff at all");
       }, kRender + "--volume s", 1, "b.tif"},
      {"tiff", "ingest of truncated data", file("v.tif", good.substr(0, good.size() - 10)), "ingest v.tif s.zarr", 1,
       "v.tif"},
  };
}

std::vector<Case> zarr_cases() {
  const std::string r = kRender + "--volume s.zarr";
  const std::string ooc = r + " --cache-mb 16 --brick 8 --block 8";
  const auto zarray = [](const std::string& from, const std::string& to) {
    return store("s.zarr", [=](const fs::path& s) { edit(s / "0" / ".zarray", from, to); });
  };
  const auto zarray_raw = [](const std::string& from, const std::string& to) {
    return store("s.zarr", [=](const fs::path& s) { edit(s / "0" / ".zarray", from, to); }, true);
  };
  const auto chunk = [](std::function<void(const fs::path&)> fn, bool raw = false) {
    return store("s.zarr", [=](const fs::path& s) { fn(first_chunk(s / "0")); }, raw);
  };
  return {
      {"zarr", "no .zarray", store("s.zarr", [](const fs::path& s) { fs::remove(s / "0" / ".zarray"); }), r, 1, "s.zarr"},
      {"zarr", "empty .zarray", store("s.zarr", [](const fs::path& s) { write_bytes(s / "0" / ".zarray", ""); }), r, 1,
       "s.zarr"},
      {"zarr", ".zarray truncated", store("s.zarr", [](const fs::path& s) { truncate_to(s / "0" / ".zarray", 30); }), r,
       1, "s.zarr"},
      {"zarr", ".zarray is a directory",
       store("s.zarr", [](const fs::path& s) { fs::remove(s / "0" / ".zarray"); fs::create_directory(s / "0" / ".zarray"); }),
       r, 1, "s.zarr"},
      {"zarr", "negative shape", zarray("\"shape\": [\n    16", "\"shape\": [\n    -16"), r, 1, "s.zarr"},
      {"zarr", "zero shape", zarray("\"shape\": [\n    16", "\"shape\": [\n    0"), r, 1, "s.zarr"},
      {"zarr", "absurd shape", zarray("\"shape\": [\n    16", "\"shape\": [\n    1000000000000"), r, 1, "s.zarr"},
      {"zarr", "shape overflows a double", zarray("\"shape\": [\n    16", "\"shape\": [\n    1e999"), r, 1, "s.zarr"},
      {"zarr", "two axes", zarray("\"shape\": [\n    16,", "\"shape\": ["), r, 1, "s.zarr"},
      {"zarr", "zero chunks", zarray("\"chunks\": [\n    8", "\"chunks\": [\n    0"), r, 1, "s.zarr"},
      {"zarr", "absurd chunks", zarray("\"chunks\": [\n    8", "\"chunks\": [\n    2000000000"), r, 1, "s.zarr"},
      {"zarr", "float64", zarray("|u1", "<f8"), r, 1, "s.zarr"},
      {"zarr", "int16", zarray("|u1", "<i2"), r, 1, "s.zarr"},
      {"zarr", "control bytes in dtype", zarray("|u1", "\\u0007\\u001b"), r, 1, "s.zarr"},
      {"zarr", "Fortran order", zarray("\"order\": \"C\"", "\"order\": \"F\""), r, 1, "s.zarr"},
      {"zarr", "a filter", zarray("\"filters\": null", "\"filters\": [{\"id\": \"delta\"}]"), r, 1, "s.zarr"},
      {"zarr", "unknown compressor", zarray_raw("\"compressor\": null", "\"compressor\": {\"id\": \"lzma\"}"), r, 1,
       "s.zarr"},
      {"zarr", "bad separator", zarray("\"dimension_separator\": \"/\"", "\"dimension_separator\": \"|\""), r, 1,
       "s.zarr"},
      {"zarr", "bad fill value", zarray("\"fill_value\": 0.0", "\"fill_value\": \"lots\""), r, 1, "s.zarr"},
      {"zarr", "zarr v3", store("s.zarr", [](const fs::path& s) {
         fs::remove(s / ".zattrs");
         fs::remove(s / ".zgroup");
         write_bytes(s / "zarr.json", "{\"zarr_format\": 3, \"node_type\": \"group\"}");
       }), r, 1, "s.zarr"},
      {"zarr", "malformed .zattrs", store("s.zarr", [](const fs::path& s) { truncate_to(s / ".zattrs", 50); }), r, 1,
       "s.zarr"},
      {"zarr", "deeply nested .zattrs",
       store("s.zarr", [](const fs::path& s) { write_bytes(s / ".zattrs", "{\"multiscales\": " + nest(100000) + "}"); }),
       r, 1, "s.zarr"},
      {"zarr", "no datasets", store("s.zarr", [](const fs::path& s) {
         write_bytes(s / ".zattrs", "{\"multiscales\": [{\"version\": \"0.4\", \"datasets\": []}]}");
       }), r, 1, "s.zarr"},
      {"zarr", "dataset path missing", store("s.zarr", [](const fs::path& s) { edit(s / ".zattrs", "\"path\": \"1\"", "\"path\": \"7\""); }),
       r, 1, "s.zarr"},
      {"zarr", "level ratio 3", store("s.zarr", [](const fs::path& s) {
         edit(s / "1" / ".zarray", "\"shape\": [\n    8,\n    8,\n    8", "\"shape\": [\n    6,\n    6,\n    6");
       }), r, 1, "s.zarr"},
      {"zarr", "dtype changes between levels", store("s.zarr", [](const fs::path& s) { edit(s / "1" / ".zarray", "|u1", "<u2"); }),
       r, 1, "s.zarr"},
      {"zarr", "chunk truncated (in core)", chunk([](const fs::path& c) { truncate_to(c, fs::file_size(c) / 2); }), r,
       1, "s.zarr"},
      {"zarr", "chunk garbage (in core)", chunk([](const fs::path& c) { write_bytes(c, Bytes(300, '\x42')); }), r, 1,
       "s.zarr"},
      {"zarr", "chunk of the wrong size (raw)", chunk([](const fs::path& c) { truncate_to(c, 100); }, true), r, 1,
       "s.zarr"},
      {"zarr", "chunk too long (raw)", chunk([](const fs::path& c) { write_bytes(c, Bytes(513, '\x01')); }, true), r, 1,
       "s.zarr"},
      {"zarr", "chunk is a directory", chunk([](const fs::path& c) { fs::remove(c); fs::create_directory(c); }), r, 1,
       "s.zarr"},
      {"zarr", "labels of float type",
       store("s.zarr", [](const fs::path& s) {
         edit(s / "labels" / "labels" / "0" / ".zarray", "<u2", "<f4");
         edit(s / "labels" / "labels" / "1" / ".zarray", "<u2", "<f4");
       }), ooc, 1, "s.zarr"},
      {"zarr", "labels of other dims",
       store("s.zarr", [](const fs::path& s) {
         edit(s / "labels" / "labels" / "0" / ".zarray", "\"shape\": [\n    16", "\"shape\": [\n    15");
       }), ooc, 1, "s.zarr"},
      {"zarr", "labels .zattrs malformed",
       store("s.zarr", [](const fs::path& s) { truncate_to(s / "labels" / ".zattrs", 10); }), ooc, 1, "s.zarr"},
      {"zarr", "out of core: no .zarray", store("s.zarr", [](const fs::path& s) { fs::remove(s / "0" / ".zarray"); }),
       ooc, 1, "s.zarr"},
      {"zarr", "out of core: unknown dtype", zarray("|u1", "<c8"), ooc, 1, "s.zarr"},
      {"zarr", "--labels store of other dims",
       [](const fs::path& d) {
         fs::copy(g_templates->store, d / "s.zarr", fs::copy_options::recursive);
         fs::copy(g_templates->store, d / "l.zarr", fs::copy_options::recursive);
         edit(d / "l.zarr" / "0" / ".zarray", "\"shape\": [\n    16", "\"shape\": [\n    12");
       }, ooc + " --labels l.zarr", 1, "l.zarr"},
      {"zarr", "info of a bad store", zarray("|u1", "<f8"), "info s.zarr", 1, "s.zarr"},
      {"zarr", "info --stats of a corrupt chunk", chunk([](const fs::path& c) { write_bytes(c, Bytes(300, '\x42')); }),
       "info --stats s.zarr", 1, "s.zarr"},
      {"zarr", ".zarray of 100 MiB", store("s.zarr", [](const fs::path& s) {
         fs::resize_file(s / "0" / ".zarray", std::uintmax_t(100) << 20);  // sparse
       }), r, 1, "s.zarr: level 0 (array '0'): '.zarray' is 100 MiB"},
      {"zarr", "not a store at all", [](const fs::path& d) { fs::create_directory(d / "s.zarr"); }, r, 1, "s.zarr"},
  };
}

std::vector<Case> json_cases() {
  const auto tf = [](const std::string& text) { return file("tf.json", text); };
  const auto cam = [](const std::string& text) { return file("cam.json", text); };
  const auto path = [](const std::string& text) { return file("p.json", text); };
  const std::string rt = kRenderSmall + "--tf tf.json";
  const std::string rc = kRenderSmall + "--camera cam.json";
  const std::string bp = "bench --volume builtin:neurites:16x16x16 --size 8x8 --methods none --path p.json";
  return {
      {"json", "tf: empty", tf(""), rt, 1, "tf.json: malformed JSON"},
      {"json", "tf: truncated", tf(kTf.substr(0, 30)), rt, 1, "tf.json: malformed JSON"},
      {"json", "tf: an array", tf("[1, 2, 3]"), rt, 1, "tf.json: "},
      {"json", "tf: no points", tf("{\"pts\": []}"), rt, 1, "tf.json: "},
      {"json", "tf: empty points", tf("{\"points\": []}"), rt, 1, "tf.json: "},
      {"json", "tf: points not an array", tf("{\"points\": 7}"), rt, 1, "tf.json: "},
      {"json", "tf: value a string", tf(replaced(kTf, "\"value\":0", "\"value\":\"zero\"")), rt, 1, "tf.json: "},
      {"json", "tf: values descending", tf(replaced(kTf, "\"value\":255", "\"value\":-5")), rt, 1, "tf.json: "},
      {"json", "tf: three components", tf(replaced(kTf, "[1,1,1,1]", "[1,1,1]")), rt, 1, "tf.json: "},
      {"json", "tf: component out of range", tf(replaced(kTf, "[1,1,1,1]", "[1,2,1,1]")), rt, 1, "tf.json: "},
      {"json", "tf: value overflows", tf(replaced(kTf, "\"value\":255", "\"value\":1e999")), rt, 1,
       "tf.json: malformed JSON"},
      {"json", "tf: deep nesting", tf("{\"points\": " + nest(100000) + "}"), rt, 1, "tf.json: "},
      {"json", "tf: a directory", [](const fs::path& d) { fs::create_directory(d / "tf.json"); }, rt, 1,
       "tf.json: is a directory"},
      {"json", "tf: missing", kNothing, rt, 1, "tf.json: "},
      {"json", "tf: control bytes", tf("{\"po\x07ints\x1b[31m\": 1}"), rt, 1, "tf.json: "},
      {"json", "tf: invalid UTF-8", tf("{\"points\": \"\xff\xfe\"}"), rt, 1, "tf.json: "},
      {"json", "tf: 4 GiB", [](const fs::path& d) {
         write_bytes(d / "tf.json", "{\"points\": [");
         fs::resize_file(d / "tf.json", std::uintmax_t(4) << 30);  // sparse: no disk used
       }, rt, 1, "tf.json: is 4096 MiB; JSON files are read and parsed whole in memory"},
      {"json", "tf: a device without end", kNothing, kRenderSmall + "--tf /dev/zero", 1,
       "/dev/zero: holds more than 64 MiB"},
      {"json", "camera: two components", cam(replaced(kCam, "[40,40,40]", "[40,40]")), rc, 1, "cam.json: "},
      {"json", "camera: eye at the centre", cam(replaced(kCam, "[40,40,40]", "[8,8,8]")), rc, 1, "cam.json: "},
      {"json", "camera: up along the view", cam(replaced(kCam, "[0,0,1]", "[1,1,1]")), rc, 1, "cam.json: "},
      {"json", "camera: zero up", cam(replaced(kCam, "[0,0,1]", "[0,0,0]")), rc, 1, "cam.json: "},
      {"json", "camera: fov 0", cam(replaced(kCam, "\"fov_deg\":30", "\"fov_deg\":0")), rc, 1, "cam.json: "},
      {"json", "camera: fov 180", cam(replaced(kCam, "\"fov_deg\":30", "\"fov_deg\":180")), rc, 1, "cam.json: "},
      {"json", "camera: unknown projection", cam(replaced(kCam, "}", ",\"projection\":\"fisheye\"}")), rc, 1,
       "cam.json: "},
      {"json", "camera: orthographic, negative height",
       cam(replaced(kCam, "}", ",\"projection\":\"orthographic\",\"height\":-3}")), rc, 1, "cam.json: "},
      {"json", "camera: number overflows", cam(replaced(kCam, "[40,40,40]", "[4e999,40,40]")), rc, 1,
       "cam.json: malformed JSON"},
      {"json", "camera: deep nesting", cam("{\"eye\": " + nest(100000) + "}"), rc, 1, "cam.json: "},
      {"json", "camera: not JSON", cam("eye = 1, 2, 3"), rc, 1, "cam.json: malformed JSON"},
      {"json", "camera: missing", kNothing, rc, 1, "cam.json: "},
      {"json", "path: keyframes a number", path("{\"frames\": 3, \"keyframes\": 7}"), bp, 1, "p.json: "},
      {"json", "path: no keyframes", path("{\"frames\": 3, \"keyframes\": []}"), bp, 1, "p.json: "},
      {"json", "path: zero frames", path(replaced(kPath, "\"frames\":3", "\"frames\":0")), bp, 1, "p.json: "},
      {"json", "path: negative frames", path(replaced(kPath, "\"frames\":3", "\"frames\":-1")), bp, 1, "p.json: "},
      {"json", "path: absurd frames", path(replaced(kPath, "\"frames\":3", "\"frames\":1e15")), bp, 1, "p.json: "},
      {"json", "path: keyframe eye at the centre", path(replaced(kPath, "[-40,40,40]", "[8,8,8]")), bp, 1, "p.json: "},
      {"json", "path: deep nesting", path("{\"frames\": 3, \"keyframes\": " + nest(100000) + "}"), bp, 1, "p.json: "},
      {"json", "path: a device without end", kNothing,
       "bench --volume builtin:neurites:16x16x16 --size 8x8 --methods none --path /dev/zero", 1,
       "/dev/zero: holds more than 64 MiB"},
      {"json", "path: truncated", path(kPath.substr(0, kPath.size() / 2)), bp, 1, "p.json: malformed JSON"},
  };
}

std::vector<Case> cli_cases() {
  const std::string base = "render --out out --volume builtin:neurites:16x16x16 ";  // no --size, --backend
  const std::string r = base + "--backend cpu --size 8x8 ";
  const Templates& t = *g_templates;
  // Gen dims whose intensity alone exceeds this machine's memory (u8, 4096 x 4096 x Z).
  const std::uint64_t z = t.phys_bytes / (4096ull * 4096ull) + 1;
  return {
      {"cli", "no command", kNothing, "", 2, "sparseleap: "},
      {"cli", "unknown command", kNothing, "paint", 2, "unknown command 'paint'"},
      {"cli", "unknown option", kNothing, r + "--colour red", 2, "--colour"},
      {"cli", "option without value", kNothing, r + "--step", 2, "--step"},
      {"cli", "--size zero", kNothing, base + "--size 0x10", 1, "--size"},
      {"cli", "--size words", kNothing, base + "--size big", 1, "--size"},
      {"cli", "--size huge", kNothing, base + "--size 100000x100000", 1, "--size"},
      {"cli", "--mode", kNothing, r + "--mode xray", 1, "--mode"},
      {"cli", "--method", kNothing, r + "--method warp", 1, "--method"},
      {"cli", "--block", kNothing, r + "--block 7", 1, "--block"},
      {"cli", "--fine-cell", kNothing, r + "--fine-cell 6", 1, "--fine-cell"},
      {"cli", "--step tiny", kNothing, r + "--step 1e-9", 1, "--step"},
      {"cli", "--step nan", kNothing, r + "--step nan", 1, "--step"},
      {"cli", "--step text", kNothing, r + "--step fast", 2, "--step"},
      {"cli", "--iso nan", kNothing, r + "--iso nan --mode iso", 2, "--iso"},
      {"cli", "--threads negative", kNothing, r + "--threads -1", 1, "--threads"},
      {"cli", "--cache-mb negative", kNothing, r + "--cache-mb -1", 1, "--cache-mb"},
      {"cli", "--brick", kNothing, r + "--cache-mb 8 --brick 12", 1, "--brick"},
      {"cli", "--lod too deep", kNothing, r + "--cache-mb 8 --lod 99", 1, "--lod"},
      {"cli", "--lod-bias negative", kNothing, r + "--cache-mb 8 --lod-bias -1", 1, "--lod-bias"},
      {"cli", "--retire-frames negative", kNothing, r + "--cache-mb 8 --retire-frames -1", 2, "--retire-frames"},
      {"cli", "--enable reversed range", kNothing, r + "--enable 5-2", 1, "--enable"},
      {"cli", "--enable bad fraction", kNothing, r + "--enable fraction:2:1", 1, "--enable"},
      {"cli", "--enable without labels", file("v.nrrd", t.nrrd), kRender + "--volume v.nrrd --enable 1", 1, "--enable"},
      {"cli", "--enable absurd id", kNothing, r + "--enable 4294967295", 1, "--enable"},
      {"cli", "--frames zero", kNothing, r + "--frames 0", 1, "--frames"},
      {"cli", "--backend", kNothing, base + "--size 8x8 --backend opencl", 1, "--backend"},
      {"cli", "--lists", kNothing, r + "--lists vulkan", 1, "--lists"},
      {"cli", "--view", kNothing, r + "--view xray", 1, "--view"},
      {"cli", "builtin kind", kNothing, kRender + "--volume builtin:nope", 1, "builtin:nope: unknown kind"},
      {"cli", "builtin zero dims", kNothing, kRender + "--volume builtin:neurites:0x16x16", 1,
       "builtin:neurites:0x16x16: dimension"},
      {"cli", "builtin more than memory", kNothing, kRender + "--volume builtin:neurites:30000x30000x30000", 1,
       "builtin:neurites:30000x30000x30000: the generated volume needs"},
      {"cli", "procedural zero dims", kNothing, kRender + "--volume procedural:neurites:0x10x10", 1, "procedural"},
      {"cli", "missing volume", kNothing, kRender + "--volume nope.nrrd", 1, "nope.nrrd"},
      {"cli", "volume is a directory", [](const fs::path& d) { fs::create_directory(d / "v.nrrd"); },
       kRender + "--volume v.nrrd", 1, "v.nrrd"},
      {"cli", "gen zero dims", kNothing, "gen blobs --dims 0x4x4 --out g.nrrd", 1, "--dims: dimension"},
      {"cli", "gen dims words", kNothing, "gen blobs --dims big --out g.nrrd", 1, "--dims"},
      {"cli", "gen unknown kind", kNothing, "gen clouds --dims 4x4x4 --out g.nrrd", 1, "clouds"},
      {"cli", "gen absurd dims", kNothing, "gen blobs --dims 9999999x9999999x9999999 --out g.nrrd", 1,
       "--dims: dims 9999999x9999999x9999999"},
      {"cli", "gen more than memory", kNothing, "gen sphere --dims 4096x4096x" + std::to_string(z) + " --out g.nrrd", 1,
       "more than half of this machine's"},
      {"cli", "gen negative seed", kNothing, "gen blobs --dims 4x4x4 --seed -1 --out g.nrrd", 2, "--seed"},
      {"cli", "ingest --chunk odd", file("v.nrrd", t.nrrd), "ingest v.nrrd s.zarr --chunk 7", 1, "--chunk"},
      {"cli", "ingest --compressor", file("v.nrrd", t.nrrd), "ingest v.nrrd s.zarr --compressor lzma", 1,
       "--compressor"},
      {"cli", "ingest --level", file("v.nrrd", t.nrrd), "ingest v.nrrd s.zarr --level 99", 1, "--level"},
      {"cli", "ingest missing input", kNothing, "ingest nope.nrrd s.zarr", 1, "nope.nrrd"},
      {"cli", "ingest empty output name", file("v.nrrd", t.nrrd), "ingest v.nrrd ''", 1, "OUT: the output name is empty"},
      {"cli", "ingest empty input name", kNothing, "ingest '' s.zarr", 1, "IN: the input name is empty"},
      {"cli", "ingest over its input", file("v.nrrd", t.nrrd), "ingest v.nrrd v.nrrd --force", 1, "is the input"},
      {"cli", "bench --orbit 0", kNothing, "bench --volume builtin:neurites:16x16x16 --orbit 0", 1, "--orbit"},
      {"cli", "bench --methods", kNothing, "bench --volume builtin:neurites:16x16x16 --methods none,warp", 1, "--method"},
      {"cli", "bench --max-frames-per-view 0", kNothing,
       "bench --volume builtin:neurites:16x16x16 --cache-mb 8 --max-frames-per-view 0", 1, "--max-frames-per-view"},
      {"cli", "info missing", kNothing, "info nope.nrrd", 1, "nope.nrrd"},
      {"cli", "control bytes in an option value", kNothing, r + "--mode \"$(printf 'x\\007\\033y')\"", 1, "--mode"},
  };
}

std::vector<Case> output_cases() {
  const std::string r = kRenderSmall;
  const Templates& t = *g_templates;
  const auto dirs = [](std::vector<std::string> names) {
    return [=](const fs::path& d) {
      for (const auto& n : names) fs::create_directories(d / n);
    };
  };
  const auto fifo = [](const std::string& name) {
    return [=](const fs::path& d) { ASSERT_EQ(::mkfifo((d / name).c_str(), 0600), 0); };
  };
  const std::string b = "bench --volume builtin:neurites:16x16x16 --size 8x8 --orbit 1 --methods none ";
  return {
      {"output", "missing folder", kNothing, "render --size 8x8 --volume builtin:neurites:16x16x16 --out no/out", 1,
       "no/out"},
      {"output", "out.exr is a directory", dirs({"out.exr"}), r, 1, "out.exr"},
      {"output", "out.png is a directory", dirs({"out.png"}), r, 1, "out.png"},
      {"output", "stats JSON is a directory", dirs({"s.json"}), r + "--stats-json s.json", 1, "s.json"},
      {"output", "stats JSON in a missing folder", kNothing, r + "--stats-json no/s.json", 1, "no/s.json"},
      {"output", "stats JSON is a FIFO without reader", fifo("s.json"), r + "--stats-json s.json", 1, "s.json"},
      {"output", "--out a full device", full_device("full"),
       "render --backend cpu --size 8x8 --volume builtin:neurites:16x16x16 --out full", 1,
       "full: cannot write file: No space left on device"},
      {"output", "--stats-json a full device", full_device("full"), r + "--stats-json full", 1,
       "full: cannot write file: No space left on device"},
      {"output", "bench --csv is a directory", dirs({"b.csv"}), b + "--csv b.csv --json b.json", 1, "b.csv"},
      {"output", "bench --json is a directory", dirs({"b.json"}), b + "--csv b.csv --json b.json", 1, "b.json"},
      {"output", "bench --json a full device", full_device("full"), b + "--csv b.csv --json full", 1,
       "full: cannot write file: No space left on device"},
      {"output", "gen into a missing folder", kNothing, "gen blobs --dims 8x8x8 --out no/g.nrrd", 1, "no/g.nrrd"},
      {"output", "gen labels into a missing folder", kNothing,
       "gen blobs --dims 8x8x8 --out g.nrrd --labels-out no/l.nrrd", 1, "no/l.nrrd"},
      {"output", "gen labels output is a directory", dirs({"l.nrrd"}),
       "gen blobs --dims 8x8x8 --out g.nrrd --labels-out l.nrrd", 1, "l.nrrd"},
      {"output", "gen detached data is a directory", dirs({"g.raw"}), "gen blobs --dims 8x8x8 --out g.nhdr", 1, "g.nhdr"},
      {"output", "ingest output exists", both(file("v.nrrd", t.nrrd), dirs({"s.zarr"})), "ingest v.nrrd s.zarr", 1,
       "s.zarr"},
      {"output", "ingest output in a missing folder", file("v.nrrd", t.nrrd), "ingest v.nrrd no/s.zarr", 1, "no/s.zarr"},
      {"output", "ingest output is a file", both(file("v.nrrd", t.nrrd), file("s.zarr", "keep me")),
       "ingest v.nrrd s.zarr", 1, "s.zarr"},
      {"output", "ingest output a device, --force", both(file("v.nrrd", t.nrrd), full_device("full")),
       "ingest v.nrrd full --force", 1, "full: exists and is not a folder"},
      {"output", "ingest output a file, --force", both(file("v.nrrd", t.nrrd), file("s.zarr", "keep me")),
       "ingest v.nrrd s.zarr --force", 1, "s.zarr: exists and is not a folder"},
  };
}

// ---- Running a case ------------------------------------------------------------------------------

// Every entry below `dir`: type, size, modification time and (small files) content.
std::map<std::string, std::string> snapshot(const fs::path& dir) {
  std::map<std::string, std::string> s;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    struct stat st {};
    ::lstat(e.path().c_str(), &st);
    // Built with append: GCC 12 warns falsely (-Wrestrict) on `" " + std::string`.
    std::string v = std::to_string(st.st_mode);
    v.append(1, ' ').append(std::to_string(st.st_size)).append(1, ' ').append(std::to_string(st.st_mtim.tv_sec));
    v.append(1, '.').append(std::to_string(st.st_mtim.tv_nsec));
    if (S_ISREG(st.st_mode) && st.st_size < (1 << 20)) {
      v.append(1, ' ').append(std::to_string(std::hash<std::string>{}(read_bytes(e.path()))));
    }
    s[fs::relative(e.path(), dir).string()] = v;
  }
  return s;
}

class BadInputCorpus : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    static Templates t;
    g_templates = &t;
    t.dir = fs::path(SL_BINARY_DIR) / "test-scratch" / "BadInputCorpus.templates";
    fs::remove_all(t.dir);
    fs::create_directories(t.dir);
    t.phys_bytes = std::uint64_t(::sysconf(_SC_PHYS_PAGES)) * std::uint64_t(::sysconf(_SC_PAGESIZE));
    GeneratedVolume g = generate_volume("blobs", ivec3(16), 1);
    write_nrrd((t.dir / "v.nrrd").string(), g.intensity);
    write_nrrd((t.dir / "l.nrrd").string(), g.labels);
    write_nrrd((t.dir / "g.nrrd").string(), g.intensity, true);
    write_nrrd((t.dir / "v.nhdr").string(), g.intensity);
    Volume f(VolumeDesc{{16, 16, 16}, vec3(1.0f), VoxelType::F32});
    write_nrrd((t.dir / "f.nrrd").string(), f);
    t.nrrd = read_bytes(t.dir / "v.nrrd");
    t.labels16 = read_bytes(t.dir / "l.nrrd");
    t.nrrd_gz = read_bytes(t.dir / "g.nrrd");
    t.labels_f32 = read_bytes(t.dir / "f.nrrd");
    t.nhdr = read_bytes(t.dir / "v.nhdr");
    t.nhdr_raw = read_bytes(t.dir / "v.raw");
    t.store = t.dir / "s.zarr";
    t.store_raw = t.dir / "raw.zarr";
    for (const auto& [s, codec] : {std::pair{t.store, "blosc-zstd"}, std::pair{t.store_raw, "none"}}) {
      const auto r = test::run_sparseleap("ingest " + (t.dir / "v.nrrd").string() + " " + s.string() + " --labels " +
                                          (t.dir / "l.nrrd").string() + " --chunk 8 --compressor " + codec);
      ASSERT_EQ(r.exit_code, 0) << r.output;
    }
  }

  // Runs one case in its own folder; what went wrong is one failure listing every problem.
  static void run_case(const Case& c, int index) {
    const fs::path dir = fs::path(SL_BINARY_DIR) / "test-scratch" / "BadInputCorpus.cases" / std::to_string(index);
    fs::remove_all(dir);
    fs::create_directories(dir);
    try {
      c.make(dir);
    } catch (const std::exception& e) {
      ADD_FAILURE() << e.what();
      return;
    }
    const auto before = snapshot(dir);
    // stderr alone through the pipe, stdout discarded; SIGKILL after the timeout (a hang is a failure).
    const test::RunResult r = test::run_shell("cd " + dir.string() + " && timeout -s KILL 60 " +
                                              test::sparseleap_exe().string() + " " + c.args + " 2>&1 >/dev/null");
    std::vector<std::string> problems;
    if (r.exit_code != c.exit) problems.push_back("exit " + std::to_string(r.exit_code) + ", expected " + std::to_string(c.exit));
    int lines = 0;
    for (char ch : r.output) lines += ch == '\n';
    if (lines != 1 || r.output.back() != '\n') problems.push_back(std::to_string(lines) + " lines on stderr, expected one");
    if (r.output.rfind("sparseleap: ", 0) != 0) problems.push_back("the line does not start with 'sparseleap: '");
    if (r.output.find(c.needle) == std::string::npos) problems.push_back("no '" + c.needle + "' in the line");
    for (std::size_t i = 0; i + 1 < r.output.size(); ++i) {
      const unsigned char ch = static_cast<unsigned char>(r.output[i]);
      if (ch < 0x20 || ch == 0x7f) {
        problems.push_back("raw control byte " + std::to_string(int(ch)) + " in the line");
        break;
      }
    }
    const auto after = snapshot(dir);
    for (const auto& [name, state] : after) {
      if (!before.count(name)) problems.push_back("left behind: " + name);
      else if (before.at(name) != state) problems.push_back("changed: " + name);
    }
    for (const auto& [name, state] : before) {
      if (!after.count(name)) problems.push_back("removed: " + name);
    }
    if (!problems.empty()) {
      std::string all;
      for (const auto& p : problems) all += "\n  - " + p;
      ADD_FAILURE() << "[" << c.format << "] " << c.name << ": sparseleap " << c.args << all << "\n  stderr: " << r.output;
    }
    fs::remove_all(dir);
  }
};

TEST_F(BadInputCorpus, EveryCaseFailsCleanlyWithOneLine) {
  std::vector<Case> all;
  for (auto* group : {nrrd_cases, nifti_cases, tiff_cases, zarr_cases, json_cases, cli_cases, output_cases}) {
    for (Case& c : group()) all.push_back(std::move(c));
  }
  std::map<std::string, int> per_format;
  std::map<std::string, int> names;
  for (const Case& c : all) {
    EXPECT_EQ(names[c.format + "/" + c.name]++, 0) << "duplicate case " << c.name;
    ++per_format[c.format];
  }
  // Two at a time (each in its own folder): the corpus also runs in the sanitizer build, where every
  // process start is slow.
  std::atomic<std::size_t> next{0};
  const auto worker = [&] {
    for (std::size_t i; (i = next++) < all.size();) run_case(all[i], int(i));
  };
  std::thread other(worker);
  worker();
  other.join();
  std::string counts;
  for (const auto& [f, n] : per_format) counts += " " + f + " " + std::to_string(n);
  std::printf("bad-input corpus: %zu cases:%s\n", all.size(), counts.c_str());
  EXPECT_GE(all.size(), 100u);
}

// Outputs that are devices are streams (core/atomic_file.h): /dev/null takes the images and the stats
// and stays /dev/null; nothing appears beside it.
TEST(OutputStreams, DevNullTakesEveryOutput) {
  const fs::path dir = test::scratch_dir();
  test::RunResult r = test::run_sparseleap("render --backend cpu --size 16x16 --volume builtin:neurites:16x16x16 "
                                           "--out /dev/null --stats-json /dev/null");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("-> /dev/null, /dev/null"), std::string::npos) << r.output;
  r = test::run_sparseleap("bench --volume builtin:neurites:16x16x16 --size 8x8 --orbit 1 --methods none --csv "
                           "/dev/null --json /dev/null");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(fs::status("/dev/null").type(), fs::file_type::character);
  EXPECT_FALSE(fs::exists("/dev/null.png"));
  EXPECT_FALSE(fs::exists("/dev/null.exr"));
  // A pipe as the stats file: the JSON arrives through it.
  r = test::run_shell(test::sparseleap_exe().string() + " render --backend cpu --size 8x8 --volume "
                      "builtin:neurites:16x16x16 --out " + (dir / "o").string() + " --stats-json /dev/stdout 2>&1 | cat");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("\"raycast\""), std::string::npos) << r.output;
}

// A label store without the `max_label` attribute (not written by our ingest) and with a corrupt
// chunk: the max-label scan skips the chunk, and out of core the render goes on with the brick
// reported and rendered as missing, instead of stopping before the first frame.
TEST(LabelStore, CorruptChunkWithoutMaxLabelRendersOutOfCore) {
  const fs::path dir = test::scratch_dir();
  GeneratedVolume g = generate_volume("neurites", ivec3(32), 1);
  write_nrrd((dir / "v.nrrd").string(), g.intensity);
  write_nrrd((dir / "l.nrrd").string(), g.labels);
  test::RunResult r = test::run_sparseleap("ingest " + (dir / "v.nrrd").string() + " " + (dir / "s.zarr").string() +
                                           " --labels " + (dir / "l.nrrd").string() + " --chunk 8 --compressor zstd");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const fs::path attrs = dir / "s.zarr" / "labels" / "labels" / ".zattrs";
  std::string a = test::read_text(attrs);
  const auto at = a.find(",\n  \"sparseleap\"");
  ASSERT_NE(at, std::string::npos) << a;
  test::write_text(attrs, a.substr(0, at) + "\n}\n");
  const fs::path chunk = first_chunk(dir / "s.zarr" / "labels" / "labels" / "0");
  test::write_text(chunk, "not zstd at all");
  const std::string out = (dir / "o").string();
  r = test::run_sparseleap("render --backend cpu --size 32x32 --cache-mb 16 --brick 8 --block 8 --lod 0 --frames 40 "
                           "--mode labels --enable all --volume " + (dir / "s.zarr").string() + " --out " + out +
                           " --stats-json " + (dir / "o.json").string());
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(out + ".png"));
  // Bricks load on worker threads, so on a busy machine the one holding the chunk may still be
  // pending after the last frame; once every brick is resolved (converged), it has been reported.
  if (test::read_text(dir / "o.json").find("\"converged_at_frame\": -1") == std::string::npos) {
    EXPECT_NE(r.output.find("warning: brick failed to load"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("corrupt"), std::string::npos) << r.output;
  }
  // In core there is no fault path: the whole label level is read, and the chunk is the error.
  r = test::run_sparseleap("render --backend cpu --size 8x8 --mode labels --volume " + (dir / "s.zarr").string() +
                           " --out " + (dir / "x").string());
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("chunk '"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace sl
