// The bad-input corpus (bad_input_harness.h) for the chunked stores' untrusted metadata: Zarr v3 with
// sharding, NGFF multiscales (on Zarr v2), Neuroglancer precomputed, and the same stores over HTTP from
// a server that answers with hostile lengths and bodies. The classes: size arithmetic that would wrap,
// keys and paths that would leave the store (percent-encoded, doubled, backslashes, symlinks), FIFOs,
// devices, directories and symlink loops where a file belongs, metadata past the 64 MiB bound, and
// voxel sizes no camera can frame.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <nlohmann/json.hpp>

#include "tests/apps/bad_input_harness.h"
#include "tests/http_test_server.h"

namespace sl::bad_input {
namespace {

using json = nlohmann::json;

struct StoreTemplates {
  fs::path zarr3;        // OME-Zarr v3 (NGFF 0.5), sharded: 16³ u8, chunks 8, shards of 2³ chunks, labels
  fs::path precomputed;  // one raw u8 scale "s0", 16³ in chunks of 8
};

std::string precomputed_info(const std::string& key = "s0", const std::string& size = "[16,16,16]",
                             const std::string& chunk = "[8,8,8]", const std::string& resolution = "[1,1,1]",
                             const std::string& extra = "") {
  return "{\"@type\":\"neuroglancer_multiscale_volume\",\"type\":\"image\",\"data_type\":\"uint8\",\"num_channels\":1,"
         "\"scales\":[{\"key\":\"" + key + "\",\"size\":" + size + ",\"resolution\":" + resolution +
         ",\"voxel_offset\":[0,0,0],\"chunk_sizes\":[" + chunk + "],\"encoding\":\"raw\"" + extra + "}]}";
}

void write_precomputed(const fs::path& d) {
  fs::create_directories(d / "s0");
  write_bytes(d / "info", precomputed_info());
  for (int z = 0; z < 16; z += 8)
    for (int y = 0; y < 16; y += 8)
      for (int x = 0; x < 16; x += 8) {
        const auto r = [](int a) { return std::to_string(a) + "-" + std::to_string(a + 8); };
        write_bytes(d / "s0" / (r(x) + "_" + r(y) + "_" + r(z)), Bytes(512, char(40 + x + y + z)));
      }
}

const StoreTemplates& store_templates() {
  static const StoreTemplates made = [] {
    const Templates& t = templates();
    StoreTemplates s;
    s.zarr3 = t.dir / "s3.zarr";
    s.precomputed = t.dir / "pc";
    const auto r = test::run_sparseleap("ingest " + (t.dir / "v.nrrd").string() + " " + s.zarr3.string() + " --labels " +
                                        (t.dir / "l.nrrd").string() + " --chunk 8 --format zarr3 --shard 2 --force");
    if (r.exit_code != 0) throw std::runtime_error("template zarr3 store: " + r.output);
    fs::remove_all(s.precomputed);
    write_precomputed(s.precomputed);
    return s;
  }();
  return made;
}

// ---- Edits --------------------------------------------------------------------------------------
void edit_json(const fs::path& p, const std::function<void(json&)>& fn) {
  json j = json::parse(read_bytes(p));
  fn(j);
  write_bytes(p, j.dump(1));
}
void make_fifo(const fs::path& p) {
  fs::remove_all(p);
  if (::mkfifo(p.c_str(), 0600) != 0) throw std::runtime_error("case setup: mkfifo " + p.string());
}
void make_loop(const fs::path& p) {
  fs::remove_all(p);
  fs::create_symlink(p.filename(), p);
}
void make_dir(const fs::path& p) {
  fs::remove_all(p);
  fs::create_directory(p);
}
void make_link(const fs::path& p, const fs::path& to) {
  fs::remove_all(p);
  fs::create_symlink(to, p);
}
// A sparse file of `n` bytes (past the 64 MiB metadata bound, costing no disk).
void make_sparse(const fs::path& p, std::uintmax_t n) {
  fs::remove_all(p);
  write_bytes(p, "{");
  fs::resize_file(p, n);
}
// The first shard (or chunk) file below an array folder: a regular file whose name is not metadata.
fs::path first_data_file(const fs::path& array) {
  std::vector<fs::path> files;
  for (const auto& e : fs::recursive_directory_iterator(array)) {
    const std::string n = e.path().filename().string();
    if (e.is_regular_file() && n != "zarr.json" && n[0] != '.') files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  if (files.empty()) throw std::runtime_error("case setup: no data file in " + array.string());
  return files.front();
}

Make zarr3(std::function<void(const fs::path&)> fn) {
  return [=](const fs::path& d) {
    fs::copy(store_templates().zarr3, d / "s3.zarr", fs::copy_options::recursive);
    fn(d / "s3.zarr");
  };
}
Make zarr3_level0(std::function<void(json&)> fn) {
  return zarr3([=](const fs::path& s) { edit_json(s / "0" / "zarr.json", fn); });
}
Make zarr3_root(std::function<void(json&)> fn) {
  return zarr3([=](const fs::path& s) { edit_json(s / "zarr.json", fn); });
}
Make ngff(std::function<void(json&)> fn) {
  return store("s.zarr", [=](const fs::path& s) { edit_json(s / ".zattrs", fn); });
}
Make pc(std::function<void(const fs::path&)> fn) {
  return [=](const fs::path& d) {
    fs::copy(store_templates().precomputed, d / "pc", fs::copy_options::recursive);
    fn(d / "pc");
  };
}
Make pc_info(const std::string& info) {
  return pc([=](const fs::path& p) { write_bytes(p / "info", info); });
}

// The NGFF 0.4 dataset list's first path, or every level's first scale entry.
std::function<void(json&)> dataset_path(const std::string& path) {
  return [=](json& j) { j["multiscales"][0]["datasets"][0]["path"] = path; };
}
// Scales every level's scale transform along axis `back` counted from the last (0: x, 1: y, 2: z).
std::function<void(json&)> dataset_scale(double v, int back = 0) {
  return [=](json& j) {
    for (json& d : j["multiscales"][0]["datasets"]) {
      for (json& t : d["coordinateTransformations"]) {
        if (t["type"] != "scale") continue;
        json& e = t["scale"][t["scale"].size() - 1 - std::size_t(back)];
        e = e.get<double>() * v;
      }
    }
  };
}
std::function<void(json&)> global_scale(double v) {
  return [=](json& j) {
    const std::size_t n = j["multiscales"][0]["datasets"][0]["coordinateTransformations"][0]["scale"].size();
    j["multiscales"][0]["coordinateTransformations"] = json::array({{{"type", "scale"}, {"scale", json(std::vector<double>(n, v))}}});
  };
}
std::function<void(json&)> ome(std::function<void(json&)> fn) {
  return [=](json& j) { fn(j["attributes"]["ome"]); };
}

const std::string kR = kRender;

// ---- Zarr v3 (sharded) ---------------------------------------------------------------------------
std::vector<Case> zarr3_cases() {
  const std::string r = kR + "--volume s3.zarr";
  const std::int64_t big = 2147483647;
  const auto shard = [](std::vector<std::int64_t> grid, std::vector<std::int64_t> inner,
                        std::vector<std::int64_t> shape = {}) {
    return zarr3_level0([=](json& j) {
      if (!shape.empty()) j["shape"] = shape;
      j["chunk_grid"]["configuration"]["chunk_shape"] = grid;
      j["codecs"][0]["configuration"]["chunk_shape"] = inner;
    });
  };
  std::vector<Case> c = {
      // Size arithmetic.
      {"zarr3", "shard grid product wraps 2^93", shard({1, 1, 2}, {1, 1, 1}, {big, big, big}), r, 1, "overflows 64-bit"},
      {"zarr3", "inner chunks per shard wrap (5 axes)", shard({big, big, 16, 16, 16}, {1, 1, 8, 8, 8}, {1, 1, 16, 16, 16}),
       r, 1, "overflows 64-bit"},
      {"zarr3", "inner chunks per shard 2^62 (4 axes)", shard({big, 16, 16, 16}, {1, 8, 8, 8}, {1, 16, 16, 16}), r, 1,
       "shard index of"},
      {"zarr3", "shard index of 1 TiB", shard({4096, 4096, 4096}, {1, 1, 1}), r, 1, "shard index of 10995116277"},
      {"zarr3", "shard index over 64 MiB", shard({2048, 2048, 2}, {1, 1, 1}), r, 1, "shard index of"},
      {"zarr3", "shard shape 2^31-1 cubed, inner 1", shard({big, big, big}, {1, 1, 1}), r, 1, "s3.zarr"},
      {"zarr3", "inner chunk past 1 GiB", shard({2048, 2048, 512}, {2048, 2048, 512}), r, 1, "exceed the 1 GiB limit"},
      {"zarr3", "inner chunk wraps", shard({big, big, big}, {big, big, big}), r, 1, "overflows 64-bit"},
      {"zarr3", "shape past 2^31", zarr3_level0([](json& j) { j["shape"] = {16, 16, 4294967296LL}; }), r, 1, "shape"},
      {"zarr3", "negative shard shape", shard({-16, 16, 16}, {8, 8, 8}), r, 1, "out of range"},
      {"zarr3", "zero inner chunk", shard({16, 16, 16}, {0, 8, 8}), r, 1, "does not divide"},
      {"zarr3", "inner chunk larger than shard", shard({16, 16, 16}, {32, 8, 8}), r, 1, "does not divide"},
      {"zarr3", "shape product past 2^63 bytes", zarr3_level0([&](json& j) { j["shape"] = {big, big, big}; }), r, 1,
       "s3.zarr"},
      {"zarr3", "grid of 0 shards cannot happen (shape 1)", shard({big, big, big}, {big, big, 1}, {1, 1, 1}), r, 1,
       "s3.zarr"},
      // Members of an unexpected JSON type: the metadata's fault (exit 1), never an internal error.
      {"zarr3", "chunk_key_encoding name is a number", zarr3_level0([](json& j) { j["chunk_key_encoding"]["name"] = 5; }), r,
       1, "unexpected JSON type"},
      {"zarr3", "node_type is a list", zarr3_level0([](json& j) { j["node_type"] = json::array(); }), r, 1,
       "unexpected JSON type"},
      {"zarr3", "index_location is a number", zarr3_level0([](json& j) { j["codecs"][0]["configuration"]["index_location"] = 1; }),
       r, 1, "unexpected JSON type"},
      {"zarr3", "root node_type is a number", zarr3_root([](json& j) { j["node_type"] = 3; }), r, 1, "unexpected JSON type"},
      {"zarr3", "axis name is a number", zarr3_root(ome([](json& j) { j["multiscales"][0]["axes"][0]["name"] = 7; })), r, 1,
       "s3.zarr"},
      // Non-regular files and loops.
      {"zarr3", "root zarr.json is a FIFO", zarr3([](const fs::path& s) { make_fifo(s / "zarr.json"); }), r, 1, "FIFO"},
      {"zarr3", "level zarr.json is a FIFO", zarr3([](const fs::path& s) { make_fifo(s / "0" / "zarr.json"); }), r, 1,
       "FIFO"},
      {"zarr3", "level 1 zarr.json is a FIFO", zarr3([](const fs::path& s) { make_fifo(s / "1" / "zarr.json"); }), r, 1,
       "FIFO"},
      {"zarr3", "labels zarr.json is a FIFO", zarr3([](const fs::path& s) { make_fifo(s / "labels" / "zarr.json"); }), r,
       1, "FIFO"},
      {"zarr3", "shard is a FIFO", zarr3([](const fs::path& s) { make_fifo(first_data_file(s / "0")); }), r, 1, "FIFO"},
      {"zarr3", "root zarr.json is a directory", zarr3([](const fs::path& s) { make_dir(s / "zarr.json"); }), r, 1,
       "is a directory"},
      {"zarr3", "shard is a directory", zarr3([](const fs::path& s) { make_dir(first_data_file(s / "0")); }), r, 1,
       "is a directory"},
      {"zarr3", "shard is /dev/zero", zarr3([](const fs::path& s) { make_link(first_data_file(s / "0"), "/dev/zero"); }),
       r, 1, "character device"},
      {"zarr3", "zarr.json symlink loop", zarr3([](const fs::path& s) { make_loop(s / "zarr.json"); }), r, 1,
       "too many levels of symbolic links"},
      {"zarr3", "level zarr.json symlink loop", zarr3([](const fs::path& s) { make_loop(s / "0" / "zarr.json"); }), r, 1,
       "too many levels of symbolic links"},
      {"zarr3", "shard symlink loop", zarr3([](const fs::path& s) { make_loop(first_data_file(s / "0")); }), r, 1,
       "too many levels of symbolic links"},
      {"zarr3", "shard symlinked out of the store",
       zarr3([](const fs::path& s) {
         const fs::path f = first_data_file(s / "0");
         fs::copy_file(f, s.parent_path() / "outside.bin");
         make_link(f, s.parent_path() / "outside.bin");
       }),
       r, 1, "outside the store"},
      {"zarr3", "level zarr.json symlinked out of the store",
       zarr3([](const fs::path& s) {
         fs::copy_file(s / "0" / "zarr.json", s.parent_path() / "z.json");
         make_link(s / "0" / "zarr.json", "../../z.json");
       }),
       r, 1, "outside the store"},
      {"zarr3", "zarr.json of 65 MiB", zarr3([](const fs::path& s) { make_sparse(s / "zarr.json", 65u << 20); }), r, 1,
       "MiB"},
      {"zarr3", "level zarr.json of 1 TiB", zarr3([](const fs::path& s) { make_sparse(s / "0" / "zarr.json", 1ull << 40); }),
       r, 1, "MiB"},
      // Shard contents.
      {"zarr3", "shard shorter than its index",
       zarr3([](const fs::path& s) { truncate_to(first_data_file(s / "0"), 10); }), r, 1, "s3.zarr"},
      {"zarr3", "shard index entry past 2^64",
       zarr3([](const fs::path& s) {
         const fs::path f = first_data_file(s / "0");
         Bytes b = read_bytes(f);
         poke<std::uint64_t>(b, b.size() - 8 * 16 - 4, ~std::uint64_t(0) - 3);
         write_bytes(f, b);
       }),
       r, 1, "s3.zarr"},
      // Dataset paths out of the store (NGFF 0.5).
      {"zarr3", "dataset path ../other.zarr", zarr3_root(ome(dataset_path("../other.zarr/0"))), r, 1, "'..' segment"},
      {"zarr3", "dataset path %2e%2e", zarr3_root(ome(dataset_path("%2e%2e/other.zarr/0"))), r, 1, "'..' segment"},
      {"zarr3", "dataset path absolute", zarr3_root(ome(dataset_path("/tmp/x.zarr/0"))), r, 1, "absolute path"},
      {"zarr3", "dataset path with backslashes", zarr3_root(ome(dataset_path("..\\other.zarr\\0"))), r, 1, "backslash"},
      {"zarr3", "dataset scale 1e30", zarr3_root(ome(dataset_scale(1e30))), r, 1, "scale 1e+30"},
      {"zarr3", "dataset scale denormal", zarr3_root(ome(dataset_scale(1e-310))), r, 1, "is outside 1e-12..1e12"},
  };
  return c;
}

// ---- NGFF multiscales (Zarr v2) --------------------------------------------------------------------
std::vector<Case> ngff_cases() {
  const std::string r = kR + "--volume s.zarr";
  std::vector<Case> c;
  const std::vector<std::pair<std::string, std::string>> paths = {
      {"../other.zarr/0", "'..' segment"},   {"..", "'..' segment"},           {"0/../../other", "'..' segment"},
      {"%2e%2e/other.zarr/0", "'..' segment"}, {"%2E%2E%2Fother", "'..' segment"}, {"%2e./x", "'..' segment"},
      {"%252e%252e/x", "'..' segment"},      {"/etc", "absolute path"},       {"%2Fetc", "absolute path"},
      {"0\\..\\..\\x", "backslash"},          {"0%5c..%5cx", "backslash"},      {"0//1", "empty segment"},
      {"0?x", "'?'"},                        {"0#x", "'#'"},                   {"%zz", "percent-escape"},
      {"0%00", "control byte"}};
  for (const auto& [p, needle] : paths) {
    c.push_back({"ngff", "dataset path " + p, ngff(dataset_path(p)), r, 1, needle});
  }
  const std::vector<std::pair<std::string, double>> scales = {
      {"0", 0.0}, {"negative", -1.0}, {"1e30", 1e30}, {"1e13", 1e13}, {"denormal 1e-310", 1e-310},
      {"smallest double", 4.9e-324}, {"1e-13", 1e-13}};
  for (const auto& [name, v] : scales) {
    c.push_back({"ngff", "scale " + name, ngff(dataset_scale(v)), r, 1, "s.zarr"});
  }
  c.push_back({"ngff", "scale 1e30 along x names the file", ngff(dataset_scale(1e30, 0)), r, 1, ".zattrs: dataset 0 scale 1e+30 along x"});
  c.push_back({"ngff", "global scale 1e20 times dataset scale", ngff(global_scale(1e20)), r, 1, "is outside 1e-12..1e12"});
  c.push_back({"ngff", "global scale 1e-20", ngff(global_scale(1e-20)), r, 1, "is outside 1e-12..1e12"});
  c.push_back({"ngff", "scale NaN as a string", ngff([](json& j) {
                 json& s = j["multiscales"][0]["datasets"][0]["coordinateTransformations"][0]["scale"];
                 s[s.size() - 1] = "NaN";
               }),
               r, 1, "positive numbers"});
  c.push_back({"ngff", "label name ../..", store("s.zarr", [](const fs::path& s) {
                 edit_json(s / "labels" / ".zattrs", [](json& j) { j["labels"] = {"../../other"}; });
               }),
               r, 1, "'..' segment"});
  c.push_back({"ngff", "label name %2e%2e", store("s.zarr", [](const fs::path& s) {
                 edit_json(s / "labels" / ".zattrs", [](json& j) { j["labels"] = {"%2e%2e/%2e%2e/x"}; });
               }),
               r, 1, "'..' segment"});
  c.push_back({"ngff", "max pyramid ../other", ngff([](json& j) { j["sparseleap"] = {{"max_pyramid", "../other"}}; }), r,
               1, "'..' segment"});
  c.push_back({"ngff", ".zattrs is a FIFO", store("s.zarr", [](const fs::path& s) { make_fifo(s / ".zattrs"); }), r, 1,
               "FIFO"});
  c.push_back({"ngff", ".zarray is a FIFO", store("s.zarr", [](const fs::path& s) { make_fifo(s / "0" / ".zarray"); }),
               r, 1, "FIFO"});
  c.push_back({"ngff", "level 1 .zarray is a FIFO",
               store("s.zarr", [](const fs::path& s) { make_fifo(s / "1" / ".zarray"); }), r, 1, "FIFO"});
  c.push_back({"ngff", "labels .zattrs is a FIFO",
               store("s.zarr", [](const fs::path& s) { make_fifo(s / "labels" / ".zattrs"); }), r, 1, "FIFO"});
  c.push_back({"ngff", "chunk is a FIFO", store("s.zarr", [](const fs::path& s) { make_fifo(first_chunk(s / "0")); }), r,
               1, "FIFO"});
  c.push_back({"ngff", ".zattrs symlink loop", store("s.zarr", [](const fs::path& s) { make_loop(s / ".zattrs"); }), r,
               1, "too many levels of symbolic links"});
  c.push_back({"ngff", ".zarray symlink loop", store("s.zarr", [](const fs::path& s) { make_loop(s / "0" / ".zarray"); }),
               r, 1, "too many levels of symbolic links"});
  c.push_back({"ngff", "chunk symlink loop", store("s.zarr", [](const fs::path& s) { make_loop(first_chunk(s / "0")); }),
               r, 1, "too many levels of symbolic links"});
  c.push_back({"ngff", ".zattrs is /dev/zero", store("s.zarr", [](const fs::path& s) { make_link(s / ".zattrs", "/dev/zero"); }),
               r, 1, "character device"});
  c.push_back({"ngff", ".zattrs of 65 MiB", store("s.zarr", [](const fs::path& s) { make_sparse(s / ".zattrs", 65u << 20); }),
               r, 1, "MiB"});
  c.push_back({"ngff", "chunk symlinked out of the store", store("s.zarr", [](const fs::path& s) {
                 const fs::path f = first_chunk(s / "0");
                 fs::copy_file(f, s.parent_path() / "outside.bin");
                 make_link(f, s.parent_path() / "outside.bin");
               }),
               r, 1, "outside the store"});
  c.push_back({"ngff", "level folder symlinked to another store", store("s.zarr", [](const fs::path& s) {
                 fs::copy(s / "0", s.parent_path() / "other0", fs::copy_options::recursive);
                 make_link(s / "0", s.parent_path() / "other0");
               }),
               r, 1, "outside the store"});
  c.push_back({"ngff", "the store is a FIFO", [](const fs::path& d) { make_fifo(d / "s.zarr"); }, r, 1, "s.zarr"});
  return c;
}

// ---- Neuroglancer precomputed --------------------------------------------------------------------
std::vector<Case> precomputed_cases() {
  const std::string r = kR + "--volume precomputed://pc";
  const std::string r_plain = kR + "--volume pc";
  std::vector<Case> c;
  const std::vector<std::pair<std::string, std::string>> keys = {
      {"%2e%2e/pc/s0", "'..' segment"}, {"%2E%2E%2Fpc%2Fs0", "'..' segment"}, {"..%2fpc/s0", "'..' segment"},
      {"%2e%2E/x", "'..' segment"},     {"%252e%252e/x", "'..' segment"},     {"s0/..", "'..' segment"},
      {"/etc", "absolute path"},        {"%2fetc", "absolute path"},          {"..\\\\x", "backslash"},
      {"s0%5c..", "backslash"},         {"a//b", "empty segment"},            {"s0?x=1", "'?'"},
      {"%", "percent-escape"},          {".", "inside the volume"}};
  for (const auto& [k, needle] : keys) c.push_back({"precomputed", "key " + k, pc_info(precomputed_info(k)), r, 1, needle});
  const std::vector<std::pair<std::string, std::string>> res = {
      {"0", "is not positive"}, {"-1", "is not positive"}, {"1e30", "is outside"}, {"1e-320", "is outside"},
      {"1e13", "is outside"}, {"5e-13", "is outside"}};
  for (const auto& [v, needle] : res) {
    c.push_back({"precomputed", "resolution " + v, pc_info(precomputed_info("s0", "[16,16,16]", "[8,8,8]", "[1," + v + ",1]")),
                 r, 1, needle});
  }
  c.push_back({"precomputed", "chunk voxels wrap to 0",
               pc_info(precomputed_info("s0", "[16,16,16]", "[1073741824,1073741824,16]")), r, 1, "chunk voxels"});
  c.push_back({"precomputed", "chunk voxels wrap (2^90)",
               pc_info(precomputed_info("s0", "[16,16,16]", "[1073741824,1073741824,1073741824]")), r, 1, "overflows 64-bit"});
  c.push_back({"precomputed", "chunk past 2^24 voxels", pc_info(precomputed_info("s0", "[16,16,16]", "[512,512,512]")), r, 1,
               "more than 2^24 voxels"});
  const std::string sharding = ",\"sharding\":{\"@type\":\"neuroglancer_uint64_sharded_v1\",\"preshift_bits\":0,"
                               "\"hash\":\"identity\",\"minishard_bits\":0,\"shard_bits\":0}";
  c.push_back({"precomputed", "sharded chunk ids past 64 bits",
               pc_info(precomputed_info("s0", "[1073741824,1073741824,1073741824]", "[1,1,1]", "[1,1,1]", sharding)), r, 1,
               "bits of sharded chunk id"});
  c.push_back({"precomputed", "minishard bits 40",
               pc_info(precomputed_info("s0", "[16,16,16]", "[8,8,8]", "[1,1,1]",
                                        ",\"sharding\":{\"@type\":\"neuroglancer_uint64_sharded_v1\",\"preshift_bits\":0,"
                                        "\"hash\":\"identity\",\"minishard_bits\":40,\"shard_bits\":0}")),
               r, 1, "exceeds 32"});
  c.push_back({"precomputed", "minishard index of 1 TiB", pc([=](const fs::path& p) {
                 write_bytes(p / "info", precomputed_info("s0", "[16,16,16]", "[8,8,8]", "[1,1,1]", sharding));
                 Bytes shard(16, '\0');
                 poke<std::uint64_t>(shard, 0, 0);
                 poke<std::uint64_t>(shard, 8, std::uint64_t(1) << 40);
                 write_bytes(p / "s0" / "0.shard", shard);
               }),
               r, 1, "minishard index of 1099511627776 bytes"});
  c.push_back({"precomputed", "sharded chunk of 1 TiB", pc([=](const fs::path& p) {
                 write_bytes(p / "info", precomputed_info("s0", "[16,16,16]", "[8,8,8]", "[1,1,1]", sharding));
                 Bytes shard(16 + 24, '\0');
                 poke<std::uint64_t>(shard, 0, 0);
                 poke<std::uint64_t>(shard, 8, 24);
                 poke<std::uint64_t>(shard, 16, 0);                          // chunk id 0
                 poke<std::uint64_t>(shard, 24, 24);                         // after the minishard index
                 poke<std::uint64_t>(shard, 32, std::uint64_t(1) << 40);     // 1 TiB
                 write_bytes(p / "s0" / "0.shard", shard);
               }),
               r, 1, "chunk of 1099511627776 bytes"});
  c.push_back({"precomputed", "info is a FIFO", pc([](const fs::path& p) { make_fifo(p / "info"); }), r, 1, "FIFO"});
  c.push_back({"precomputed", "info is a FIFO (no prefix)", pc([](const fs::path& p) { make_fifo(p / "info"); }), r_plain, 1,
               "pc"});
  c.push_back({"precomputed", "info is a directory", pc([](const fs::path& p) { make_dir(p / "info"); }), r, 1,
               "is a directory"});
  c.push_back({"precomputed", "info symlink loop", pc([](const fs::path& p) { make_loop(p / "info"); }), r, 1,
               "too many levels of symbolic links"});
  c.push_back({"precomputed", "info symlink loop (no prefix)", pc([](const fs::path& p) { make_loop(p / "info"); }),
               r_plain, 1, "pc"});
  c.push_back({"precomputed", "info symlink loop (info command)", pc([](const fs::path& p) { make_loop(p / "info"); }),
               "info precomputed://pc", 1, "too many levels of symbolic links"});
  c.push_back({"precomputed", "info is /dev/zero", pc([](const fs::path& p) { make_link(p / "info", "/dev/zero"); }), r, 1,
               "character device"});
  c.push_back({"precomputed", "info of 65 MiB", pc([](const fs::path& p) { make_sparse(p / "info", 65u << 20); }), r, 1,
               "MiB"});
  c.push_back({"precomputed", "info symlinked out of the store", pc([](const fs::path& p) {
                 write_bytes(p.parent_path() / "info.out", precomputed_info());
                 make_link(p / "info", "../info.out");
               }),
               r, 1, "outside the store"});
  c.push_back({"precomputed", "chunk is a FIFO", pc([](const fs::path& p) { make_fifo(p / "s0" / "0-8_0-8_0-8"); }), r, 1,
               "FIFO"});
  c.push_back({"precomputed", "chunk symlink loop", pc([](const fs::path& p) { make_loop(p / "s0" / "0-8_0-8_0-8"); }), r,
               1, "too many levels of symbolic links"});
  c.push_back({"precomputed", "scale folder symlinked out", pc([](const fs::path& p) {
                 fs::copy(p / "s0", p.parent_path() / "s0.out", fs::copy_options::recursive);
                 make_link(p / "s0", "../s0.out");
               }),
               r, 1, "outside the store"});
  c.push_back({"precomputed", "shard is a FIFO", pc([=](const fs::path& p) {
                 write_bytes(p / "info", precomputed_info("s0", "[16,16,16]", "[8,8,8]", "[1,1,1]", sharding));
                 make_fifo(p / "s0" / "0.shard");
               }),
               r, 1, "FIFO"});
  return c;
}

// ---- HTTP -------------------------------------------------------------------------------------------
// The served root: copies of the templates under names the cases use, and one edited copy per case
// that needs its own metadata.
struct Served {
  fs::path root;
  std::unique_ptr<test::HttpTestServer> server;
};

Served& served() {
  static Served s = [] {
    Served v;
    v.root = templates().dir.parent_path() / "http_root";  // beside the templates (scratch_dir() would empty them)
    fs::remove_all(v.root);
    fs::create_directories(v.root);
    fs::copy(templates().store, v.root / "z.zarr", fs::copy_options::recursive);
    fs::copy(store_templates().zarr3, v.root / "z3.zarr", fs::copy_options::recursive);
    write_precomputed(v.root / "pc");
    v.server = std::make_unique<test::HttpTestServer>(v.root, "--hostile");
    return v;
  }();
  return s;
}

std::vector<Case> http_cases() {
  Served& s = served();
  const std::string url = s.server->url();
  std::vector<Case> c;
  const auto r = [&](const std::string& spec) { return kR + "--volume " + spec; };
  // Precomputed keys that a server would decode to a path outside the store's URL.
  int serial = 0;
  const auto pc_key = [&](const std::string& key, const std::string& needle) {
    const std::string name = "pck" + std::to_string(serial++);
    write_precomputed(s.root / name);
    write_bytes(s.root / name / "info", precomputed_info(key));
    c.push_back({"http", "precomputed key " + key, kNothing, r("precomputed://" + url + "/" + name), 1, needle});
  };
  pc_key("%2e%2e/pc/s0", "'..' segment");
  pc_key("%2E%2E%2Fpc%2Fs0", "'..' segment");
  pc_key("..%2Fpc/s0", "'..' segment");
  pc_key("%252e%252e/pc/s0", "'..' segment");
  pc_key("%2e%2e%5cpc", "backslash");
  pc_key("s0%3F", "'?'");
  pc_key("s0%23", "'#'");
  pc_key("/pc/s0", "absolute path");
  const auto ngff_path = [&](const std::string& path) {
    const std::string name = "ng" + std::to_string(serial++) + ".zarr";
    fs::copy(templates().store, s.root / name, fs::copy_options::recursive);
    edit_json(s.root / name / ".zattrs", dataset_path(path));
    c.push_back({"http", "NGFF dataset path " + path, kNothing, r(url + "/" + name), 1, "'..' segment"});
  };
  ngff_path("../z.zarr/0");
  ngff_path("%2e%2e/z.zarr/0");
  ngff_path("%2E%2E%2Fz.zarr%2F0");
  {
    const std::string name = "ng3.zarr";
    fs::copy(store_templates().zarr3, s.root / name, fs::copy_options::recursive);
    edit_json(s.root / name / "zarr.json", ome(dataset_path("%2e%2e/z3.zarr/0")));
    c.push_back({"http", "NGFF 0.5 dataset path %2e%2e", kNothing, r(url + "/" + name), 1, "'..' segment"});
  }
  // Hostile answers to metadata reads, through every kind of store.
  const std::vector<std::pair<std::string, std::string>> prefixes = {
      {"precomputed://", ""}, {"zarr3://", ""}, {"zarr2://", ""}, {"", ".zarr"}};
  for (const std::string hostile : {"hostile-huge-length", "hostile-endless", "hostile-bad-length",
                                    "hostile-chunked-garbage", "hostile-long-header"}) {
    for (const auto& [prefix, suffix] : prefixes) {
      const std::string spec = prefix + url + "/" + hostile + suffix;
      c.push_back({"http", hostile + " via " + (prefix.empty() ? "a .zarr name" : prefix), kNothing, r(spec), 1, hostile});
    }
  }
  c.push_back({"http", "metadata announced past 64 MiB names the bound", kNothing,
               r("precomputed://" + url + "/hostile-huge-length"), 1, "over the 67108864 bytes (64 MiB) bound"});
  c.push_back({"http", "metadata streamed past 64 MiB names the bound", kNothing,
               r("precomputed://" + url + "/hostile-endless"), 1, "more than the 67108864 bytes (64 MiB) bound"});
  // Size arithmetic and voxel sizes over HTTP.
  {
    const std::string name = "big3.zarr";
    fs::copy(store_templates().zarr3, s.root / name, fs::copy_options::recursive);
    edit_json(s.root / name / "0" / "zarr.json", [](json& j) {
      j["shape"] = {2147483647, 2147483647, 2147483647};
      j["chunk_grid"]["configuration"]["chunk_shape"] = {1, 1, 2};
      j["codecs"][0]["configuration"]["chunk_shape"] = {1, 1, 1};
    });
    c.push_back({"http", "zarr3 shard grid wraps", kNothing, r(url + "/" + name), 1, "overflows 64-bit"});
    const std::string pcname = "pcres";
    write_precomputed(s.root / pcname);
    write_bytes(s.root / pcname / "info", precomputed_info("s0", "[16,16,16]", "[8,8,8]", "[1e30,1,1]"));
    c.push_back({"http", "precomputed resolution 1e30", kNothing, r("precomputed://" + url + "/" + pcname), 1, "is outside"});
    const std::string pcwrap = "pcwrap";
    write_precomputed(s.root / pcwrap);
    write_bytes(s.root / pcwrap / "info", precomputed_info("s0", "[16,16,16]", "[1073741824,1073741824,16]"));
    c.push_back({"http", "precomputed chunk voxels wrap", kNothing, r("precomputed://" + url + "/" + pcwrap), 1,
                 "chunk voxels"});
    const std::string ngs = "ngscale.zarr";
    fs::copy(templates().store, s.root / ngs, fs::copy_options::recursive);
    edit_json(s.root / ngs / ".zattrs", dataset_scale(1e-310));
    c.push_back({"http", "NGFF scale denormal", kNothing, r(url + "/" + ngs), 1, "is outside 1e-12..1e12"});
  }
  c.push_back({"http", "no info", kNothing, r("precomputed://" + url + "/nothing-here"), 1, "no 'info' file"});
  return c;
}

// ---- Every other input path the command line takes: a FIFO, device, loop or directory there ---------
std::vector<Case> input_path_cases() {
  const std::string small = kRenderSmall;
  const auto fifo = [](const std::string& name) { return [=](const fs::path& d) { make_fifo(d / name); }; };
  const auto loop = [](const std::string& name) { return [=](const fs::path& d) { make_loop(d / name); }; };
  std::vector<Case> c = {
      {"inputs", "--volume .nrrd is a FIFO", fifo("v.nrrd"), kR + "--volume v.nrrd", 1, "v.nrrd: is a FIFO"},
      {"inputs", "--volume .nhdr is a FIFO", fifo("v.nhdr"), kR + "--volume v.nhdr", 1, "v.nhdr: is a FIFO"},
      {"inputs", "detached NRRD data file is a FIFO",
       both(file("v.nhdr", templates().nhdr), fifo("v.raw")), kR + "--volume v.nhdr", 1, "FIFO"},
      {"inputs", "--volume .nii is a FIFO", fifo("v.nii"), kR + "--volume v.nii", 1, "v.nii: is a FIFO"},
      {"inputs", "--volume .nii.gz is a FIFO", fifo("v.nii.gz"), kR + "--volume v.nii.gz", 1, "FIFO"},
      {"inputs", "--volume .tif is a FIFO", fifo("v.tif"), kR + "--volume v.tif", 1, "v.tif: is a FIFO"},
      {"inputs", "a TIFF slice in a stack is a FIFO", [](const fs::path& d) { fs::create_directory(d / "stack"); make_fifo(d / "stack" / "a.tif"); },
       kR + "--volume stack", 1, "FIFO"},
      {"inputs", "a TIFF slice in a stack is a symlink loop",
       [](const fs::path& d) { fs::create_directory(d / "stack"); make_loop(d / "stack" / "a.tif"); }, kR + "--volume stack", 1,
       "too many levels of symbolic links"},
      {"inputs", "--labels .nrrd is a FIFO", both(file("v.nrrd", templates().nrrd), fifo("l.nrrd")),
       kR + "--volume v.nrrd --labels l.nrrd", 1, "l.nrrd: is a FIFO"},
      {"inputs", "--tf is a FIFO", fifo("tf.json"), small + "--tf tf.json", 1, "tf.json: is a FIFO"},
      {"inputs", "--camera is a FIFO", fifo("cam.json"), small + "--camera cam.json", 1, "cam.json: is a FIFO"},
      {"inputs", "--tf is a symlink loop", loop("tf.json"), small + "--tf tf.json", 1, "too many levels of symbolic links"},
      {"inputs", "--camera is /dev/zero", [](const fs::path& d) { make_link(d / "cam.json", "/dev/zero"); },
       small + "--camera cam.json", 1, "character device"},
      {"inputs", "--volume .nrrd is a symlink loop", loop("v.nrrd"), kR + "--volume v.nrrd", 1,
       "too many levels of symbolic links"},
      {"inputs", "info of a FIFO", fifo("v.nrrd"), "info v.nrrd", 1, "FIFO"},
      {"inputs", "ingest from a FIFO", fifo("v.nrrd"), "ingest v.nrrd o.zarr", 1, "FIFO"},
  };
  return c;
}

TEST(BadInputCorpus, InputPathsThatAreNotFiles) { run_corpus(input_path_cases()); }
TEST(BadInputCorpus, Zarr3Sharded) { run_corpus(zarr3_cases()); }
TEST(BadInputCorpus, NgffMultiscales) { run_corpus(ngff_cases()); }
TEST(BadInputCorpus, Precomputed) { run_corpus(precomputed_cases()); }
TEST(BadInputCorpus, Http) { run_corpus(http_cases()); }

// The templates themselves render: every case above is one edit away from a good store.
TEST(BadInputCorpus, StoreTemplatesRender) {
  const fs::path d = templates().dir.parent_path() / "store_templates_render";
  fs::remove_all(d);
  fs::create_directories(d);
  const std::string out = " --backend cpu --size 8x8 --out " + (d / "o").string();
  for (const std::string& v : {store_templates().zarr3.string(), "precomputed://" + store_templates().precomputed.string(),
                               served().server->url() + "/z.zarr", "precomputed://" + served().server->url() + "/pc",
                               served().server->url() + "/z3.zarr"}) {
    const test::RunResult r = test::run_sparseleap("render --volume " + v + out);
    EXPECT_EQ(r.exit_code, 0) << v << ": " << r.output;
  }
}

}  // namespace
}  // namespace sl::bad_input
