// TIFF stacks: inputs the fuzzer (tests/fuzz) found mishandled, kept as regressions; the good paths
// are in ingest_test.cpp (stacks made by python3-tifffile).
#include <gtest/gtest.h>

#include <string>

#include "cache/formats/volume_file.h"
#include "core/util/error.h"

namespace sl {
namespace {

std::string fuzz_case(const std::string& name) { return std::string(SL_SOURCE_DIR) + "/tests/fuzz/corpus/tiff/" + name; }

TEST(TiffStack, ACorruptTileWidthIsRefusedBeforeItsBufferIsAllocated) {
  // 32x16 u16 page whose TileWidth tag says 268435456: the tile buffer would have been 8 GiB.
  try {
    read_volume_file(fuzz_case("regress_huge_tile_width.tif"));
    FAIL() << "read a TIFF with a 268435456-pixel tile width";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("bad tile size 268435456x16 for a 32x16 page"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace sl
