// AtomicFile: a file is complete under its name or absent; nothing but regular files is replaced
// (devices and FIFOs are written in place); the temporary never survives a failure.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <set>

#include "core/util/atomic_file.h"
#include "core/util/error.h"
#include "core/util/image.h"
#include "tests/test_util.h"

namespace sl {
namespace {

namespace fs = std::filesystem;

std::set<std::string> listing(const fs::path& dir) {
  std::set<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.insert(e.path().filename().string());
  return names;
}

// Runs fn, which must throw InputError naming `file` with `needle` in its reason.
template <class Fn>
void expect_input_error(Fn&& fn, const std::string& file, const std::string& needle) {
  try {
    fn();
    ADD_FAILURE() << "no InputError for " << file;
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), file);
    EXPECT_NE(e.reason().find(needle), std::string::npos) << e.what();
    EXPECT_EQ(std::string(e.what()), file + ": " + e.reason());  // the `FILE: reason` style
  }
}

TEST(AtomicFile, WritesTheBytesAndLeavesOnlyTheFile) {
  const fs::path dir = test::scratch_dir();
  const std::string p = (dir / "a.json").string();
  write_file_atomic(p, "{\"x\": 1}\n");
  EXPECT_EQ(test::read_text(p), "{\"x\": 1}\n");
  write_file_atomic(p, "second");  // replaces a regular file
  EXPECT_EQ(test::read_text(p), "second");
  EXPECT_EQ(listing(dir), std::set<std::string>{"a.json"});
}

TEST(AtomicFile, NothingAppearsBeforeCommitAndTheTemporaryIsHiddenBeside) {
  const fs::path dir = test::scratch_dir();
  {
    AtomicFile f(dir / "out.bin");
    f.write("abc");
    EXPECT_FALSE(fs::exists(dir / "out.bin"));
    EXPECT_EQ(f.temp_path().parent_path(), dir);
    EXPECT_EQ(f.temp_path().filename().string().rfind(".out.bin.part-", 0), 0u) << f.temp_path();
    f.close();
    EXPECT_TRUE(fs::exists(f.temp_path()));
    f.commit();
    EXPECT_FALSE(fs::exists(f.temp_path()));
  }
  EXPECT_EQ(test::read_text(dir / "out.bin"), "abc");
  EXPECT_EQ(listing(dir), std::set<std::string>{"out.bin"});
}

TEST(AtomicFile, AnUncommittedFileRemovesItsTemporary) {
  const fs::path dir = test::scratch_dir();
  write_file_atomic((dir / "keep.txt").string(), "old");
  try {
    AtomicFile f(dir / "keep.txt");
    f.write("new, half written");
    throw std::runtime_error("the writer failed");
  } catch (const std::runtime_error&) {
  }
  EXPECT_EQ(test::read_text(dir / "keep.txt"), "old");  // the previous file is untouched
  EXPECT_EQ(listing(dir), std::set<std::string>{"keep.txt"});
}

TEST(AtomicFile, ALibraryMayWriteTheTemporaryByName) {
  const fs::path dir = test::scratch_dir();
  {
    AtomicFile f(dir / "by_name.txt");
    test::write_text(f.temp_path(), "written by someone else");
    f.commit();
  }
  EXPECT_EQ(test::read_text(dir / "by_name.txt"), "written by someone else");
}

TEST(AtomicFile, RefusesToReplaceADirectoryAndLeavesIt) {
  const fs::path dir = test::scratch_dir();
  fs::create_directories(dir / "taken" / "inner");
  const std::string p = (dir / "taken").string();
  expect_input_error([&] { write_file_atomic(p, "x"); }, p, "cannot write file: it is a directory");
  EXPECT_TRUE(fs::is_directory(dir / "taken" / "inner"));
  EXPECT_EQ(listing(dir), std::set<std::string>{"taken"});
}

// A character device or FIFO is a stream: written in place, never replaced, its write errors named.
TEST(AtomicFile, WritesDevNullAndAFifoInPlaceAndNamesTheirErrors) {
  write_file_atomic("/dev/null", "x");
  EXPECT_EQ(fs::status("/dev/null").type(), fs::file_type::character);
  expect_input_error([] { write_file_atomic("/dev/full", "x"); }, "/dev/full", "No space left on device");
  EXPECT_EQ(fs::status("/dev/full").type(), fs::file_type::character);
  const fs::path dir = test::scratch_dir();
  const fs::path fifo = dir / "pipe";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  // Nobody reads it: an error at once, not a hang.
  expect_input_error([&] { write_file_atomic(fifo.string(), "x"); }, fifo.string(), "FIFO without a reader");
  const int reader = ::open(fifo.c_str(), O_RDONLY | O_NONBLOCK);
  ASSERT_GE(reader, 0);
  write_file_atomic(fifo.string(), "through the pipe");
  char buf[64] = {};
  EXPECT_EQ(::read(reader, buf, sizeof buf), 16);
  EXPECT_EQ(std::string(buf), "through the pipe");
  ::close(reader);
  EXPECT_EQ(fs::status(fifo).type(), fs::file_type::fifo);
  EXPECT_EQ(listing(dir), std::set<std::string>{"pipe"});
}

TEST(AtomicFile, CheckOutputFileRefusesWhatTheWriterWould) {
  const fs::path dir = test::scratch_dir();
  fs::create_directory(dir / "taken");
  expect_input_error([&] { check_output_file(dir / "taken"); }, (dir / "taken").string(), "it is a directory");
  const std::string missing = (dir / "no" / "f.txt").string();
  expect_input_error([&] { check_output_file(missing); }, missing, "folder '" + (dir / "no").string() + "' does not exist");
  EXPECT_NO_THROW(check_output_file(dir / "new.txt"));
  EXPECT_NO_THROW(check_output_file("/dev/null"));
  EXPECT_TRUE(is_stream_file("/dev/null"));
  EXPECT_FALSE(is_stream_file(dir / "new.txt"));
  EXPECT_EQ(listing(dir), std::set<std::string>{"taken"});
}

TEST(AtomicFile, ADirectoryAppearingBeforeCommitIsRefusedToo) {
  const fs::path dir = test::scratch_dir();
  AtomicFile f(dir / "late");
  f.write("x");
  fs::create_directory(dir / "late");
  expect_input_error([&] { f.commit(); }, (dir / "late").string(), "directory");
  EXPECT_TRUE(fs::is_directory(dir / "late"));
}

TEST(AtomicFile, MissingOrUnwritableFolderNamesTheFileWithTheSystemReason) {
  const fs::path dir = test::scratch_dir();
  const std::string missing = (dir / "no" / "f.txt").string();
  expect_input_error([&] { write_file_atomic(missing, "x"); }, missing, "No such file or directory");
  if (::geteuid() != 0) {  // root ignores permissions
    fs::create_directories(dir / "ro");
    fs::permissions(dir / "ro", fs::perms::owner_read | fs::perms::owner_exec);
    const std::string ro = (dir / "ro" / "f.txt").string();
    expect_input_error([&] { write_file_atomic(ro, "x"); }, ro, "Permission denied");
    fs::permissions(dir / "ro", fs::perms::owner_all);
  }
}

TEST(AtomicFile, ErrorsNameWhoTheUserGaveAndTheFileWritten) {
  const fs::path dir = test::scratch_dir();
  fs::create_directories(dir / "data.raw");
  expect_input_error([&] { AtomicFile f(dir / "data.raw", "header.nhdr"); }, "header.nhdr",
                     "cannot write '" + (dir / "data.raw").string() + "': it is a directory");
}

TEST(AtomicFile, ImagesGoThroughIt) {
  const fs::path dir = test::scratch_dir();
  Image img(3, 2);
  fs::create_directory(dir / "f.png");
  fs::create_directory(dir / "f.exr");
  expect_input_error([&] { write_png((dir / "f.png").string(), img); }, (dir / "f.png").string(), "directory");
  expect_input_error([&] { write_exr((dir / "f.exr").string(), img); }, (dir / "f.exr").string(), "directory");
  write_png((dir / "g.png").string(), img);
  write_exr((dir / "g.exr").string(), img);
  EXPECT_EQ(listing(dir), (std::set<std::string>{"f.exr", "f.png", "g.exr", "g.png"}));
}

}  // namespace
}  // namespace sl
