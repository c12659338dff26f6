// NIfTI through libnifti2 (cache/formats/nifti/nifti.h) against nibabel (tests/data_tools/nifti_tool.py):
// NIfTI-1 and -2, single files and .hdr/.img pairs, gzip, both byte orders, scl_slope/scl_inter, read
// voxel for voxel; the orientation `info` reports from the sform.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "cache/formats/nifti/nifti.h"
#include "cache/formats/volume_file.h"
#include "tests/cache/formats/zarr_test_util.h"
#include "tests/test_util.h"

namespace sl {
namespace {

namespace fs = std::filesystem;

int run_nifti_peer(const std::string& args, std::string* out) {
  const test::RunResult r = test::run_shell(std::string(test::kPeerPython) + " " + SL_SOURCE_DIR +
                                            "/tests/data_tools/nifti_tool.py write " + args + " 2>&1");
  *out = r.output;
  return r.exit_code;
}

struct PeerCase {
  std::string file, args;
  VoxelType type;
};

TEST(Nifti, ReadsWhatNibabelWritesVoxelForVoxel) {
  SL_REQUIRE_PYTHON("nibabel, numpy");
  const fs::path dir = test::scratch_dir();
  const std::vector<PeerCase> cases = {
      {"a.nii", "--dtype u1 --spacing 0.5,0.75,2", VoxelType::U8},
      {"b.nii.gz", "--dtype i2", VoxelType::F32},  // int16: float32, values kept
      {"c.nii", "--dtype u2 --version 2", VoxelType::U16},
      {"d.nii.gz", "--dtype f4 --version 2 --big-endian", VoxelType::F32},
      {"e.hdr", "--dtype u2 --big-endian", VoxelType::U16},  // a pair, opened by its header
      {"f.img.gz", "--dtype i1 --version 2", VoxelType::F32},  // a gzip pair, opened by its image
      {"g.nii", "--dtype u4", VoxelType::U32},
      {"h.nii", "--dtype u2 --scaled", VoxelType::F32},
      {"i.hdr.gz", "--dtype i2 --scaled --version 2 --big-endian", VoxelType::F32},
  };
  for (const PeerCase& c : cases) {
    SCOPED_TRACE(c.file + " " + c.args);
    const fs::path path = dir / c.file, expected = dir / (c.file + ".expected");
    std::string out;
    ASSERT_EQ(run_nifti_peer(path.string() + " " + expected.string() + " --shape 13,22,30 " + c.args, &out), 0)
        << out;
    const Volume v = read_volume_file(path.string());
    EXPECT_EQ(v.desc().dims, ivec3(30, 22, 13));
    EXPECT_EQ(v.type(), c.type);
    if (c.file == "a.nii") {
      EXPECT_EQ(v.desc().spacing, vec3(0.5f, 0.75f, 2.0f));
    }
    const std::vector<std::byte> want = test::read_bytes(expected);
    ASSERT_EQ(want.size(), v.desc().byte_size());
    EXPECT_EQ(std::memcmp(want.data(), v.data(), want.size()), 0);
  }
}

TEST(Nifti, InfoReportsFormatScalingAndOrientationFromTheSform) {
  SL_REQUIRE_PYTHON("nibabel, numpy");
  const fs::path dir = test::scratch_dir();
  std::string out;
  for (const std::string a : {"ras", "lps", "las"}) {
    ASSERT_EQ(run_nifti_peer((dir / (a + ".nii")).string() + " " + (dir / a).string() + " --shape 3,4,5 --affine " + a,
                             &out),
              0)
        << out;
  }
  ASSERT_EQ(run_nifti_peer((dir / "s.hdr").string() + " " + (dir / "s").string() + " --shape 3,4,5 --dtype u1 "
                               "--scaled --version 2",
                           &out),
            0)
      << out;
  // nibabel writes the affine as an sform of code 2 (aligned).
  EXPECT_EQ(nifti_info((dir / "ras.nii").string()).orientation, "RAS (sform: aligned)");
  EXPECT_EQ(nifti_info((dir / "lps.nii").string()).orientation, "LPS (sform: aligned)");
  EXPECT_EQ(nifti_info((dir / "las.nii").string()).orientation, "LAS (sform: aligned)");
  const NiftiInfo s = nifti_info((dir / "s.hdr").string());
  EXPECT_EQ(s.format, "NIfTI-2, .hdr/.img pair, UINT8 stored");
  EXPECT_EQ(s.scaling, "slope 37.5 inter -100000 (read as f32)");
  EXPECT_EQ(nifti_info((dir / "ras.nii").string()).scaling, "none");

  const test::RunResult r = test::run_sparseleap("info " + (dir / "lps.nii").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("orientation LPS (sform: aligned)"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("format  NIfTI-1, single file"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace sl
