// A local store reads regular files only, opened without blocking (a FIFO where a chunk or metadata
// object belongs is refused at once, never waited on), and never more than the caller's bound; the
// same holds for every JSON input the command line reads.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <fcntl.h>

#include <chrono>
#include <cstdio>
#include <functional>
#include <filesystem>
#include <string>

#include "cache/stores/byte_store.h"
#include "core/util/error.h"
#include "core/util/input_file.h"
#include "core/util/json_util.h"
#include "tests/test_util.h"

namespace sl {
namespace {

namespace fs = std::filesystem;

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "(no error)";
}

class LocalStoreInputs : public ::testing::Test {
 protected:
  void SetUp() override {
    dir = test::scratch_dir() / "local_store_inputs";
    fs::remove_all(dir);
    fs::create_directories(dir / "s" / "sub");
    test::write_text(dir / "s" / "obj", std::string(1000, 'x'));
    ASSERT_EQ(::mkfifo((dir / "s" / "fifo").c_str(), 0600), 0);
    fs::create_symlink("loop", dir / "s" / "loop");
    fs::create_symlink("/dev/zero", dir / "s" / "zero");
    fs::create_symlink("fifo", dir / "s" / "to_fifo");
    // A bound socket (a UNIX socket file).
    const int sock = ::socket(AF_UNIX, SOCK_STREAM, 0);
    sockaddr_un a{};
    a.sun_family = AF_UNIX;
    const std::string sp = (dir / "s" / "sock").string();
    if (sp.size() < sizeof a.sun_path) {
      std::snprintf(a.sun_path, sizeof a.sun_path, "%s", sp.c_str());
      have_socket = ::bind(sock, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
    }
    ::close(sock);
  }
  void TearDown() override { fs::remove_all(dir); }
  fs::path dir;
  bool have_socket = false;
};

TEST_F(LocalStoreInputs, NonRegularObjectsAreRefusedAtOnceWithWhatTheyAre) {
  const LocalByteStore s((dir / "s").string());
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_NE(error_of([&] { s.read("fifo", kMaxMetadataBytes); }).find("is a FIFO (named pipe), not a regular file"),
            std::string::npos);
  EXPECT_NE(error_of([&] { s.read_range("fifo", 0, 16); }).find("FIFO"), std::string::npos);
  EXPECT_NE(error_of([&] { s.read_suffix("fifo", 16); }).find("FIFO"), std::string::npos);
  EXPECT_NE(error_of([&] { s.read("to_fifo", 16); }).find("FIFO"), std::string::npos);
  EXPECT_NE(error_of([&] { s.read("sub", 16); }).find("is a directory"), std::string::npos);
  EXPECT_NE(error_of([&] { s.read("zero", 16); }).find("character device"), std::string::npos);
  EXPECT_NE(error_of([&] { s.read("loop", 16); }).find("too many levels of symbolic links"), std::string::npos);
  if (have_socket) {
    EXPECT_NE(error_of([&] { s.read("sock", 16); }).find("socket"), std::string::npos);
  }
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(5));  // nothing waited for a writer
  EXPECT_FALSE(s.read("absent", 16).has_value());
  EXPECT_FALSE(s.size_if_known("fifo").has_value());
}

TEST_F(LocalStoreInputs, WholeReadsAreBoundedBeforeAllocating) {
  const LocalByteStore s((dir / "s").string());
  EXPECT_EQ(s.read("obj", 1000)->size(), 1000u);
  EXPECT_NE(error_of([&] { s.read("obj", 999); }).find("file of 1000 bytes exceeds the 999 bytes bound"), std::string::npos);
  // A sparse file of 1 TiB: refused from its size, never read.
  {
    const int fd = ::open((dir / "s" / "huge").c_str(), O_WRONLY | O_CREAT, 0600);
    ASSERT_GE(fd, 0);
    ASSERT_EQ(::ftruncate(fd, off_t(1) << 40), 0);
    ::close(fd);
  }
  EXPECT_NE(error_of([&] { s.read("huge", kMaxMetadataBytes); }).find("exceeds the 67108864 bytes (64 MiB) bound"),
            std::string::npos);
}

TEST_F(LocalStoreInputs, JsonInputsRefuseFifosDevicesDirectoriesAndLoops) {
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_NE(error_of([&] { read_file_text((dir / "s" / "fifo").string()); }).find("fifo: is a FIFO"), std::string::npos);
  EXPECT_NE(error_of([&] { read_file_text((dir / "s" / "sub").string()); }).find("is a directory"), std::string::npos);
  EXPECT_NE(error_of([&] { read_file_text((dir / "s" / "zero").string()); }).find("character device"), std::string::npos);
  EXPECT_NE(error_of([&] { read_file_text((dir / "s" / "loop").string()); }).find("too many levels of symbolic links"),
            std::string::npos);
  EXPECT_NE(error_of([&] { read_file_text((dir / "s" / "absent").string()); }).find("cannot open file"), std::string::npos);
  EXPECT_EQ(read_file_text((dir / "s" / "obj").string()).size(), 1000u);
  EXPECT_NE(error_of([&] { check_input_file((dir / "s" / "fifo").string()); }).find("FIFO"), std::string::npos);
  EXPECT_THROW(open_input_file((dir / "s" / "to_fifo").string()), InputError);
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(5));
}

}  // namespace
}  // namespace sl
