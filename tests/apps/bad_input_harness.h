// The harness of the bad-input corpus, shared by the bad_input_*_test.cpp files, one per
// format: broken inputs made from our own writers (or a few lines of header bytes) plus a byte edit,
// each run as a user or a script would run it. Every case must end with the expected exit status (1
// bad input or data, 2 command-line syntax), exactly one line on stderr that names the file or option
// and the problem (no raw control bytes), no signal and no sanitizer report, within a timeout, and
// leave its working folder exactly as it was (no output, no temporary, nothing replaced).
#pragma once

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
#include <functional>
#include <map>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "cache/formats/nrrd/nrrd.h"
#include "core/scene/generate.h"
#include "core/scene/volume.h"
#include "tests/test_util.h"

namespace sl::bad_input {

namespace fs = std::filesystem;

using Bytes = std::string;

inline Bytes read_bytes(const fs::path& p) { return test::read_text(p); }
inline void write_bytes(const fs::path& p, const Bytes& b) { test::write_text(p, b); }

// Replaces the first `from` in `b` (it must be there: a case that edits nothing tests nothing).
inline Bytes replaced(Bytes b, const std::string& from, const std::string& to) {
  const auto pos = b.find(from);
  if (pos == std::string::npos) throw std::runtime_error("case setup: '" + from + "' not found");
  return b.replace(pos, from.size(), to);
}
inline void edit(const fs::path& p, const std::string& from, const std::string& to) {
  write_bytes(p, replaced(read_bytes(p), from, to));
}
inline void truncate_to(const fs::path& p, std::size_t n) { fs::resize_file(p, n); }

template <class T> inline void poke(Bytes& b, std::size_t offset, T v) { std::memcpy(b.data() + offset, &v, sizeof v); }

struct Templates {
  fs::path dir;
  Bytes nrrd, nrrd_gz, labels16, labels_f32, nhdr;  // attached u8 16³, gzip, its u16 labels, f32, detached
  Bytes nhdr_raw;
  fs::path store, store_raw;  // OME-Zarr with labels (blosc-zstd; uncompressed)
  std::uint64_t phys_bytes = 0;
};

// The inputs the cases edit, made once per test program from our own writers.
inline const Templates& templates() {
  static const Templates made = [] {
    Templates t;
    t.dir = test::scratch_dir() / "templates";  // the test's own: ctest runs the formats in parallel
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
      if (r.exit_code != 0) throw std::runtime_error("template store: " + r.output);
    }
    return t;
  }();
  return made;
}

inline const std::string kTf = R"({"points":[{"value":0,"rgba":[0,0,0,0]},{"value":255,"rgba":[1,1,1,1]}]})";
inline const std::string kCam = R"({"eye":[40,40,40],"center":[8,8,8],"up":[0,0,1],"fov_deg":30})";
inline const std::string kPath = R"({"frames":3,"keyframes":[{"eye":[40,40,40],"center":[8,8,8],"up":[0,0,1],"fov_deg":30},)"
                                 R"({"eye":[-40,40,40],"center":[8,8,8],"up":[0,0,1],"fov_deg":30}]})";

struct Case {
  std::string format;  // nrrd, nifti, tiff, zarr, json, cli, output
  std::string name;
  std::function<void(const fs::path&)> make;  // writes the case's inputs into its (empty) folder
  std::string args;    // run in that folder
  int exit = 1;        // 1 bad input or data, 2 syntax
  std::string needle;  // in the error line: the file or option and the problem
};

using Make = std::function<void(const fs::path&)>;
inline const Make kNothing = [](const fs::path&) {};
inline Make file(const std::string& name, const Bytes& bytes) {
  return [=](const fs::path& d) { write_bytes(d / name, bytes); };
}
inline Make both(Make a, Make b) {
  return [=](const fs::path& d) { a(d); b(d); };
}
inline Make store(const std::string& name, std::function<void(const fs::path&)> edit_fn, bool raw = false) {
  return [=](const fs::path& d) {
    fs::copy(raw ? templates().store_raw : templates().store, d / name, fs::copy_options::recursive);
    edit_fn(d / name);
  };
}
// The first chunk file of an array folder (sorted, so the same one every run).
inline fs::path first_chunk(const fs::path& array) {
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
inline Make full_device(const std::string& name) {
  return [=](const fs::path& d) {
    if (::geteuid() == 0) {
      ASSERT_EQ(::mknod((d / name).c_str(), S_IFCHR | 0666, ::makedev(1, 7)), 0) << std::strerror(errno);
    } else {
      fs::create_symlink("/dev/full", d / name);
    }
  };
}
inline std::string nest(int depth) { return std::string(std::size_t(depth), '[') + std::string(std::size_t(depth), ']'); }

inline const std::string kRender = "render --backend cpu --size 8x8 --out out ";
inline const std::string kRenderSmall = kRender + "--volume builtin:neurites:16x16x16 ";

// ---- Running a case ------------------------------------------------------------------------------

// Every entry below `dir`: type, size, modification time and (small files) content.
inline std::map<std::string, std::string> snapshot(const fs::path& dir) {
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
    s[e.path().lexically_relative(dir).string()] = v;  // not fs::relative: it follows symlinks (and loops)
  }
  return s;
}

// Runs one case in its own folder; what went wrong is one failure listing every problem.
inline void run_case(const Case& c, const std::string& folder) {
  const fs::path dir = fs::path(SL_BINARY_DIR) / "test-scratch" / "BadInputCorpus.cases" / folder;
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
  if (lines != 1 || r.output.empty() || r.output.back() != '\n') problems.push_back(std::to_string(lines) + " lines on stderr, expected one");
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

// Runs every case of one format, two at a time (each in its own folder): the corpus also runs in the
// sanitizer build, where every process start is slow.
inline void run_corpus(const std::vector<Case>& cases) {
  ASSERT_FALSE(cases.empty());
  std::map<std::string, int> names;
  for (const Case& c : cases) EXPECT_EQ(names[c.name]++, 0) << "duplicate case " << c.name;
  templates();  // made before the threads start
  std::atomic<std::size_t> next{0};
  const auto worker = [&] {
    for (std::size_t i; (i = next++) < cases.size();) run_case(cases[i], cases[i].format + "-" + std::to_string(i));
  };
  std::thread other(worker);
  worker();
  other.join();
  std::printf("bad-input corpus: %zu %s cases\n", cases.size(), cases.front().format.c_str());
}

}  // namespace sl::bad_input
