// recognise_store (store_kind.h): a directory is a store by what it holds, a prefix overrides that, and
// anything else is left to the volume-file readers.
#include <gtest/gtest.h>

#include <filesystem>

#include "cache/stores/store_kind.h"
#include "tests/test_util.h"

namespace sl {
namespace {

namespace fs = std::filesystem;

TEST(StoreKind, RecognisedByWhatTheDirectoryHolds) {
  const fs::path d = test::scratch_dir();
  fs::create_directories(d / "pc");
  test::write_text(d / "pc" / "info", "{}");
  fs::create_directories(d / "v3");
  test::write_text(d / "v3" / "zarr.json", "{}");
  fs::create_directories(d / "v2");
  test::write_text(d / "v2" / ".zattrs", "{}");
  fs::create_directories(d / "tiffs");
  EXPECT_EQ(recognise_store((d / "pc").string()).kind, StoreKind::Precomputed);
  EXPECT_EQ(recognise_store((d / "v3").string()).kind, StoreKind::Zarr);
  EXPECT_EQ(recognise_store((d / "v2").string()).kind, StoreKind::Zarr);
  EXPECT_EQ(recognise_store((d / "x.zarr").string()).kind, StoreKind::Zarr);  // named so, even before it exists
  EXPECT_EQ(recognise_store((d / "tiffs").string()).kind, StoreKind::None);
  EXPECT_EQ(recognise_store((d / "a.nrrd").string()).kind, StoreKind::None);
  EXPECT_EQ(recognise_store("builtin:neurites").kind, StoreKind::None);
  EXPECT_EQ(recognise_store("").kind, StoreKind::None);
  EXPECT_EQ(recognise_store((d / "pc").string()).path, (d / "pc").string());
}

TEST(StoreKind, PrefixWinsAndIsRemoved) {
  const StoreLocation p = recognise_store("precomputed:///data/em");
  EXPECT_EQ(p.kind, StoreKind::Precomputed);
  EXPECT_EQ(p.path, "/data/em");
  const StoreLocation z = recognise_store("zarr://relative/dir");
  EXPECT_EQ(z.kind, StoreKind::Zarr);
  EXPECT_EQ(z.path, "relative/dir");
}

}  // namespace
}  // namespace sl
