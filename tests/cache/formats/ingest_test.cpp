// `ingest`: the slab-by-slab pyramid equals MemoryVolumeSource's whole-volume pyramid, inputs in every
// supported format (NRRD raw/gzip, TIFF stacks and NIfTI made by python3-tifffile / python3-nibabel),
// the memory bound, and failures that never leave a store looking complete.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>

#include "cache/formats/ingest.h"
#include "cache/formats/nrrd/nrrd.h"
#include "cache/formats/zarr/source.h"
#include "cache/formats/zarr/writer.h"
#include "cache/volume_source.h"
#include "core/util/error.h"
#include "tests/cache/formats/zarr_test_util.h"
#include "tests/test_util.h"

namespace sl {
namespace {

namespace fs = std::filesystem;

Volume ramp(VoxelType t, ivec3 dims, vec3 spacing = vec3(1.0f)) {
  Volume v(VolumeDesc{dims, spacing, t});
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x) {
        const bool empty = (x / 9 + y / 9 + z / 9) % 3 == 0;  // whole empty chunks are skipped
        v.set(x, y, z, empty ? 0.0f : float((x * 11 + y * 3 + z * 17) % 200 + 1));
      }
  return v;
}

// Every brick of every level read from the store equals MemoryVolumeSource's (same reductions).
void expect_same_bricks(const VolumeSource& a, const VolumeSource& b, int brick) {
  const BrickLayout layout = BrickLayout::make(a.desc(), brick);
  ASSERT_EQ(a.has_labels(), b.has_labels());
  std::vector<std::byte> ia(std::size_t(layout.stored_voxels()) * std::size_t(voxel_size(a.desc().type))), ib(ia.size());
  std::vector<std::byte> la(a.has_labels() ? std::size_t(layout.stored_voxels()) * std::size_t(voxel_size(a.label_type())) : 0),
      lb(la.size());
  for (int l = 0; l < layout.levels; ++l) {
    const ivec3 nb = layout.bricks(l);
    for (int i = 0; i < nb.x * nb.y * nb.z; ++i) {
      const BrickId id = BrickId::pack(l, ivec3(i % nb.x, (i / nb.x) % nb.y, i / (nb.x * nb.y)));
      a.read_brick(layout, id, ia, la);
      b.read_brick(layout, id, ib, lb);
      ASSERT_EQ(ia, ib) << to_string(id);
      ASSERT_EQ(la, lb) << to_string(id) << " labels";
    }
  }
}

TEST(Ingest, PyramidMatchesMemoryVolumeSourceForEveryChunkSize) {
  const fs::path dir = test::scratch_dir();
  const ivec3 dims(45, 38, 71);  // odd sizes, deeper than several chunk layers
  auto v = std::make_shared<const Volume>(ramp(VoxelType::U16, dims, vec3(0.5f, 0.5f, 2.0f)));
  auto lab = std::make_shared<Volume>(VolumeDesc{dims, vec3(1.0f), VoxelType::U8});
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x) lab->set(x, y, z, float((x / 4 * 7 + y / 6 + z / 5 * 3) % 13));
  write_nrrd((dir / "v.nrrd").string(), *v, true);  // gzip: streamed through zlib
  write_nrrd((dir / "l.nhdr").string(), *lab);      // detached raw
  const MemoryVolumeSource ref(v, lab);
  for (int chunk : {8, 16, 32, 64}) {
    SCOPED_TRACE("chunk " + std::to_string(chunk));
    IngestOptions o;
    o.chunk = chunk;
    o.labels = (dir / "l.nhdr").string();
    o.force = true;
    std::uint64_t last = 0, calls = 0, total = 0;
    o.progress = [&](std::uint64_t done, std::uint64_t t) {
      EXPECT_GT(done, last);
      last = done;
      total = t;
      ++calls;
    };
    const IngestResult r = ingest((dir / "v.nrrd").string(), (dir / "s.zarr").string(), o);
    EXPECT_EQ(calls, std::uint64_t((dims.z + chunk - 1) / chunk));
    EXPECT_EQ(last, total);
    EXPECT_EQ(r.input_bytes, v->desc().byte_size() + lab->desc().byte_size());
    EXPECT_EQ(r.max_label, max_label(*lab));
    const ZarrVolumeSource src((dir / "s.zarr").string());
    EXPECT_EQ(src.desc().spacing, vec3(0.5f, 0.5f, 2.0f));
    EXPECT_EQ(src.stored_levels(), r.levels);
    EXPECT_EQ(src.max_label(), max_label(*lab));
    expect_same_bricks(src, ref, 8);
    expect_same_bricks(src, ref, 32);
  }
}

// The max pyramid beside the mean (docs/formats.md "Max levels"): its bricks equal MemoryVolumeSource's
// max pyramid at every level, in Zarr v2 and v3 (sharded); a store read without a choice serves it;
// the mean pyramid of the same store is unchanged; a store without max levels refuses Max.
TEST(Ingest, WritesAndReadsBackTheMaxPyramid) {
  const fs::path dir = test::scratch_dir();
  const ivec3 dims(45, 38, 71);
  auto v = std::make_shared<const Volume>(ramp(VoxelType::U16, dims));
  write_nrrd((dir / "v.nrrd").string(), *v);
  const MemoryVolumeSource mean(v, nullptr, "v", PyramidKind::Mean), max(v, nullptr, "v", PyramidKind::Max);
  for (const int format : {2, 3}) {
    SCOPED_TRACE("zarr v" + std::to_string(format));
    IngestOptions o;
    o.chunk = 16;
    o.zarr_format = format;
    o.shard = format == 3 ? 2 : 0;
    o.force = true;
    const IngestResult r = ingest((dir / "v.nrrd").string(), (dir / "s.zarr").string(), o);
    EXPECT_TRUE(fs::is_directory(dir / "s.zarr" / "max" / "1"));
    EXPECT_FALSE(fs::exists(dir / "s.zarr" / "max" / "0"));
    const ZarrVolumeSource chosen((dir / "s.zarr").string(), "", std::nullopt);
    EXPECT_EQ(chosen.pyramid(), PyramidKind::Max);
    EXPECT_EQ(chosen.stored_max_levels(), r.levels - 1);
    expect_same_bricks(chosen, max, 8);
    expect_same_bricks(ZarrVolumeSource((dir / "s.zarr").string()), mean, 8);
  }
  // A store of a writer without max levels: mean by default, Max refused naming the store.
  zarr::WriterOptions wo;
  wo.chunk = 128;  // one chunk layer holds each level: one slab each
  wo.levels = 2;
  zarr::StoreWriter w(dir / "m.zarr", "m.zarr", v->desc(), wo);
  w.write_slab(zarr::Target::Image, 0, 0, dims.z, v->data());
  const MemoryVolumeSource one(v);
  const Volume& l1 = one.level(1);
  w.write_slab(zarr::Target::Image, 1, 0, l1.dims().z, l1.data());
  EXPECT_EQ(ZarrVolumeSource((dir / "m.zarr").string(), "", std::nullopt).pyramid(), PyramidKind::Mean);
  try {
    ZarrVolumeSource((dir / "m.zarr").string(), "", PyramidKind::Max);
    ADD_FAILURE() << "Max accepted without max levels";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no max pyramid"), std::string::npos) << e.what();
  }
}

TEST(Ingest, ABareArrayReadsAsAOneLevelStore) {
  // One level's array directory alone (a .zarray, no multiscales) is a store of one level, whose
  // coarser levels are derived in memory.
  const fs::path dir = test::scratch_dir();
  auto v = std::make_shared<const Volume>(ramp(VoxelType::U8, ivec3(30, 20, 25)));
  write_nrrd((dir / "v.nrrd").string(), *v);
  IngestOptions o;
  o.chunk = 8;
  ingest((dir / "v.nrrd").string(), (dir / "s.zarr").string(), o);
  const ZarrVolumeSource src((dir / "s.zarr" / "0").string() + "/");
  EXPECT_EQ(src.stored_levels(), 1);
  expect_same_bricks(src, MemoryVolumeSource(v), 8);
}

TEST(Ingest, MemoryBoundDoesNotGrowWithDepth) {
  const VolumeDesc shallow{ivec3(2048, 2048, 64), vec3(1.0f), VoxelType::U8};
  VolumeDesc deep = shallow;
  deep.dims.z = 1 << 20;
  const std::uint64_t a = memory_bound(shallow, std::nullopt, 64), b = memory_bound(deep, std::nullopt, 64);
  const double layers = 64.0 * 2048.0 * 2048.0;
  EXPECT_GE(double(a), layers);
  // 4/3 * layer for the mean pyramid, 1/3 for the max one's levels >= 1, and per-thread chunks
  EXPECT_LE(double(b), 1.67 * layers + 64.0 * 1024.0 * 1024.0);
  EXPECT_LE(double(b) - double(a), 0.01 * layers);                // extra levels cost only their tiny layers
  EXPECT_GT(memory_bound(shallow, VoxelType::U32, 64), a * 4);    // labels add their own layers
}

TEST(Ingest, ExistingOutputNeedsForceAndIsReplacedWhole) {
  const fs::path dir = test::scratch_dir();
  write_nrrd((dir / "a.nrrd").string(), ramp(VoxelType::U8, ivec3(20, 20, 20)));
  write_nrrd((dir / "b.nrrd").string(), ramp(VoxelType::U8, ivec3(10, 12, 14)));
  IngestOptions o;
  ingest((dir / "a.nrrd").string(), (dir / "s.zarr").string(), o);
  try {
    ingest((dir / "b.nrrd").string(), (dir / "s.zarr").string(), o);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("--force"), std::string::npos) << e.what();
  }
  o.force = true;
  ingest((dir / "b.nrrd").string(), (dir / "s.zarr/").string(), o);  // a trailing slash names the same store
  EXPECT_EQ(ZarrVolumeSource((dir / "s.zarr").string()).desc().dims, ivec3(10, 12, 14));
  for (const auto& e : fs::directory_iterator(dir)) EXPECT_NE(e.path().filename().string()[0], '.') << e.path();
}

TEST(Ingest, FailureHalfwayLeavesNothing) {
  const fs::path dir = test::scratch_dir();
  write_nrrd((dir / "v.nrrd").string(), ramp(VoxelType::U16, ivec3(64, 64, 200)), true);
  const auto size = fs::file_size(dir / "v.nrrd");
  fs::resize_file(dir / "v.nrrd", size / 2);  // the gzip stream ends mid-volume
  IngestOptions o;
  o.chunk = 16;
  int slabs = 0;
  o.progress = [&](std::uint64_t, std::uint64_t) { ++slabs; };
  try {
    ingest((dir / "v.nrrd").string(), (dir / "s.zarr").string(), o);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("v.nrrd"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("truncated"), std::string::npos) << e.what();
  }
  EXPECT_GT(slabs, 0);  // it failed after writing some chunks
  EXPECT_FALSE(fs::exists(dir / "s.zarr"));
  for (const auto& e : fs::directory_iterator(dir)) EXPECT_EQ(e.path().filename(), "v.nrrd");
}

TEST(Ingest, BadOptionsAndInputs) {
  const fs::path dir = test::scratch_dir();
  write_nrrd((dir / "v.nrrd").string(), ramp(VoxelType::U8, ivec3(8, 8, 8)));
  IngestOptions o;
  o.chunk = 7;
  EXPECT_THROW(ingest((dir / "v.nrrd").string(), (dir / "s.zarr").string(), o), InputError);
  o.chunk = 64;
  EXPECT_THROW(ingest((dir / "nope.nrrd").string(), (dir / "s.zarr").string(), o), InputError);
  test::write_text(dir / "x.raw", "abc");
  EXPECT_THROW(ingest((dir / "x.raw").string(), (dir / "s.zarr").string(), o), InputError);
  EXPECT_THROW(ingest((dir / "v.nrrd").string(), (dir / "no-dir" / "s.zarr").string(), o), InputError);
  write_nrrd((dir / "f.nrrd").string(), ramp(VoxelType::F32, ivec3(8, 8, 8)));
  o.labels = (dir / "f.nrrd").string();
  EXPECT_THROW(ingest((dir / "v.nrrd").string(), (dir / "s.zarr").string(), o), InputError);
  EXPECT_THROW(zarr::compressor_from_name("lzma"), std::runtime_error);
  EXPECT_THROW(zarr::compressor_from_name("zlib", 12), std::runtime_error);
  EXPECT_FALSE(fs::exists(dir / "s.zarr"));
}

void expect_level0(const fs::path& store, const fs::path& expected, ivec3 dims, VoxelType t) {
  const Volume v = read_zarr_volume(store.string());
  EXPECT_EQ(v.dims(), dims);
  EXPECT_EQ(v.type(), t);
  const auto b = test::read_bytes(expected);
  ASSERT_EQ(b.size(), v.desc().byte_size());
  EXPECT_EQ(std::memcmp(b.data(), v.data(), b.size()), 0);
}

TEST(Ingest, TiffDirectoryAndMultipage) {
  SL_REQUIRE_PYTHON("tifffile, numpy");
  const fs::path dir = test::scratch_dir();
  std::string out;
  ASSERT_EQ(test::run_peer("tiff " + (dir / "slices").string() + " " + (dir / "e8").string() +
                               " --shape 19,23,31 --dtype u1", &out), 0) << out;
  ASSERT_EQ(test::run_peer("tiff " + (dir / "stack.tif").string() + " " + (dir / "e16").string() +
                               " --shape 21,17,40 --dtype u2 --multipage", &out), 0) << out;
  IngestOptions o;
  o.chunk = 8;
  ingest((dir / "slices").string(), (dir / "a.zarr").string(), o);
  expect_level0(dir / "a.zarr", dir / "e8", ivec3(31, 23, 19), VoxelType::U8);
  ingest((dir / "stack.tif").string(), (dir / "b.zarr").string(), o);
  expect_level0(dir / "b.zarr", dir / "e16", ivec3(40, 17, 21), VoxelType::U16);
  // A slice of another size is refused naming it.
  fs::copy_file(dir / "stack.tif", dir / "slices" / "zz_last.tif");
  try {
    ingest((dir / "slices").string(), (dir / "c.zarr").string(), o);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("zz_last.tif"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(dir / "c.zarr"));
}

TEST(Ingest, Nifti) {
  SL_REQUIRE_PYTHON("nibabel, numpy");
  const fs::path dir = test::scratch_dir();
  std::string out;
  ASSERT_EQ(test::run_peer("nifti " + (dir / "a.nii").string() + " " + (dir / "ea").string() +
                               " --shape 13,22,30 --dtype u1 --spacing 0.5,0.75,2", &out), 0) << out;
  ASSERT_EQ(test::run_peer("nifti " + (dir / "b.nii.gz").string() + " " + (dir / "eb").string() +
                               " --shape 9,14,17 --dtype i2", &out), 0) << out;
  ASSERT_EQ(test::run_peer("nifti " + (dir / "c.nii.gz").string() + " " + (dir / "ec").string() +
                               " --shape 9,14,17 --dtype u2", &out), 0) << out;
  IngestOptions o;
  o.chunk = 8;
  ingest((dir / "a.nii").string(), (dir / "a.zarr").string(), o);
  expect_level0(dir / "a.zarr", dir / "ea", ivec3(30, 22, 13), VoxelType::U8);
  EXPECT_EQ(ZarrVolumeSource((dir / "a.zarr").string()).desc().spacing, vec3(0.5f, 0.75f, 2.0f));
  ingest((dir / "b.nii.gz").string(), (dir / "b.zarr").string(), o);  // int16 -> float32, values kept
  expect_level0(dir / "b.zarr", dir / "eb", ivec3(17, 14, 9), VoxelType::F32);
  ingest((dir / "c.nii.gz").string(), (dir / "c.zarr").string(), o);
  expect_level0(dir / "c.zarr", dir / "ec", ivec3(17, 14, 9), VoxelType::U16);
  // Truncated data: a clear error, no store.
  const auto b = test::read_bytes(dir / "a.nii");
  test::write_text(dir / "t.nii", std::string(reinterpret_cast<const char*>(b.data()), b.size() / 2));
  EXPECT_THROW(ingest((dir / "t.nii").string(), (dir / "t.zarr").string(), o), InputError);
  EXPECT_FALSE(fs::exists(dir / "t.zarr"));
  test::write_text(dir / "junk.nii", std::string(400, 'x'));
  EXPECT_THROW(ingest((dir / "junk.nii").string(), (dir / "j.zarr").string(), o), InputError);
}

}  // namespace
}  // namespace sl
