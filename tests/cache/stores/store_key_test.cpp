// Keys from a store's metadata resolve inside the store or are refused: the examples (percent-encoded
// "..", mixed case, double encoding, backslashes, absolute paths, NULs), a property over arbitrary keys
// for the local and the URL form, and symlinks out of a local store.
#include "cache/stores/store_key.h"

#include <gtest/gtest.h>
#include <rapidcheck/gtest.h>

#include <filesystem>
#include <string>
#include <vector>

#include "cache/stores/byte_store.h"
#include "cache/stores/http_store.h"
#include "tests/server_path.h"
#include "tests/test_util.h"

namespace sl {
namespace {

namespace fs = std::filesystem;

std::string refusal(const std::string& key) {
  try {
    return "accepted as '" + store_key(key) + "'";
  } catch (const std::runtime_error& e) {
    return e.what();
  }
}

bool refused(const std::string& key) { return refusal(key).rfind("accepted", 0) != 0; }

TEST(StoreKey, NormalKeysPassInNormalForm) {
  EXPECT_EQ(store_key("8_8_8"), "8_8_8");
  EXPECT_EQ(store_key("0/c/0/0/0"), "0/c/0/0/0");
  EXPECT_EQ(store_key("./0/./zarr.json"), "0/zarr.json");
  EXPECT_EQ(store_key("labels/cells/"), "labels/cells");
  EXPECT_EQ(store_key("."), "");
  EXPECT_EQ(store_key(""), "");
  EXPECT_EQ(store_key("a..b/..c/d.."), "a..b/..c/d..");  // dots inside a name are no segment
  EXPECT_EQ(store_key("a%41b"), "a%41b");                 // an escape that decodes to nothing dangerous
}

TEST(StoreKey, EscapesAreRefusedInEveryEncoding) {
  for (const char* k : {"..", "../other.zarr/0", "a/../../b", "0/..", "%2e%2e/x", "%2E%2E/x", "%2e./x", ".%2E/x",
                        "a%2F..%2Fb", "a%2f%2e%2e%2fb", "%252e%252e/x", "%25252e%25252e/x", "/etc/passwd", "%2Fetc",
                        "a\\..\\b", "a%5c..%5cb", "a//b", "a%2F%2Fb", "a?x", "a#x", "a%3F", "a%00b", "a\nb", "a%0a",
                        "%", "%2", "%zz", "a%2"}) {
    EXPECT_TRUE(refused(k)) << "'" << k << "': " << refusal(k);
  }
  EXPECT_TRUE(refused(std::string("a\0b", 3)));  // a NUL inside the key (a const char* would end at it)
  EXPECT_NE(refusal("%2e%2e/x").find("key '%2e%2e/x' has a '..' segment"), std::string::npos) << refusal("%2e%2e/x");
  EXPECT_NE(refusal(std::string("a\0b", 3)).find("key 'a\\x00b' holds a control byte"), std::string::npos);
}

TEST(StoreKey, LocalAndUrlFormsJoinTheNormalKey) {
  EXPECT_EQ(local_store_path("/data/s.zarr", "./0/zarr.json"), "/data/s.zarr/0/zarr.json");
  EXPECT_EQ(local_store_path("/data/s.zarr", ""), "/data/s.zarr");
  EXPECT_EQ(store_url("http://h/s", "8_8_8/0-64_0-64_0-64"), "http://h/s/8_8_8/0-64_0-64_0-64");
  EXPECT_THROW(store_url("http://h/s", "%2e%2e/secret"), std::runtime_error);
  // The HTTP store refuses before it sends anything (no server listens here).
  const HttpByteStore http("http://127.0.0.1:9/s");
  EXPECT_THROW(http.url("../x"), std::runtime_error);
  EXPECT_THROW(http.read("%2e%2e/info", kMaxMetadataBytes), std::runtime_error);
}

rc::Gen<std::string> key_segment() {
  return rc::gen::oneOf(
      rc::gen::element<std::string>(".", "..", "%2e", "%2E", "%2e%2e", "%2E%2e", "%252e%252e", "%2f", "%2F", "%5c", "\\",
                                    "", "/", "//", "a", "0", "c", "zarr.json", "info", "%00", std::string(1, '\0'), "?",
                                    "#", "%", "%2", "..%2f", ".%2e", "%2e.", "%25", "%%2e2e"),
      rc::gen::container<std::string>(rc::gen::element('a', '.', '%', '2', 'e', 'E', 'f', 'F', '/', '\\', '5', 'c')));
}

rc::Gen<std::string> any_key() {
  return rc::gen::map(rc::gen::container<std::vector<std::string>>(key_segment()), [](const std::vector<std::string>& segs) {
    std::string k;
    for (std::size_t i = 0; i < segs.size(); ++i) k += (i ? "/" : "") + segs[i];
    return k;
  });
}

RC_GTEST_PROP(StoreKey, NoKeyResolvesOutsideItsStore, ()) {
  const std::string key = *any_key();
  const bool leading_slash = *rc::gen::arbitrary<bool>();
  const std::string k = leading_slash ? "/" + key : key;
  std::string normal;
  try {
    normal = store_key(k);
  } catch (const std::runtime_error&) {
    return;  // refused: nothing is read
  }
  // URL form: the path the server serves lies below the store's path.
  const std::string url = store_url("http://host/data/s.zarr", k);
  RC_ASSERT(url.rfind("http://host/", 0) == 0u);
  const std::string served = test::server_path(url.substr(std::string("http://host").size()));
  RC_ASSERT(served == "/data/s.zarr" || served.rfind("/data/s.zarr/", 0) == 0u);
  // Local form: the file named lies below the root.
  const fs::path local = fs::path(local_store_path("/data/s.zarr", k)).lexically_normal();
  const std::string l = local.string();
  RC_ASSERT(l == "/data/s.zarr" || l == "/data/s.zarr/" || l.rfind("/data/s.zarr/", 0) == 0u);
  RC_ASSERT(normal.find('\0') == std::string::npos);
}

TEST(StoreKey, SymlinksOutOfALocalStoreAreRefused) {
  const fs::path dir = test::scratch_dir() / "store_key_symlinks";
  fs::remove_all(dir);
  fs::create_directories(dir / "s" / "inner");
  test::write_text(dir / "secret", "outside");
  test::write_text(dir / "s" / "inner" / "obj", "inside");
  fs::create_symlink("../secret", dir / "s" / "out");
  fs::create_symlink(dir, dir / "s" / "updir");
  fs::create_symlink("inner/obj", dir / "s" / "in");
  fs::create_symlink("loop", dir / "s" / "loop");
  fs::create_symlink(dir / "s", dir / "alias");  // the root itself may be a symlink
  for (const fs::path& root : {dir / "s", dir / "alias"}) {
    SCOPED_TRACE(root.string());
    const LocalByteStore s(root.string());
    const auto in = s.read("in", 1024);
    ASSERT_TRUE(in.has_value());
    EXPECT_EQ(in->size(), 6u);
    try {
      s.read("out", 1024);
      ADD_FAILURE() << "read through a symlink out of the store";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find("outside the store"), std::string::npos) << e.what();
    }
    EXPECT_THROW(s.read("updir/secret", 1024), std::runtime_error);
    EXPECT_THROW(s.read_range("out", 0, 1), std::runtime_error);
    EXPECT_THROW(s.read_suffix("updir/secret", 1), std::runtime_error);
    try {
      s.read("loop", 1024);
      ADD_FAILURE() << "read a symlink loop";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find("too many levels of symbolic links"), std::string::npos) << e.what();
    }
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace sl
