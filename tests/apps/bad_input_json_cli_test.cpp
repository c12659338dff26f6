// The bad-input corpus (bad_input_harness.h): transfer-function, camera and camera-path JSON, and
// command-line values.
#include <gtest/gtest.h>


#include "tests/apps/bad_input_harness.h"

namespace sl::bad_input {
namespace {

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
       "/dev/zero: is a character device, not a regular file"},
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
       "/dev/zero: is a character device, not a regular file"},
      {"json", "path: truncated", path(kPath.substr(0, kPath.size() / 2)), bp, 1, "p.json: malformed JSON"},
  };
}

std::vector<Case> cli_cases() {
  const std::string base = "render --out out --volume builtin:neurites:16x16x16 ";  // no --size, --backend
  const std::string r = base + "--backend cpu --size 8x8 ";
  const Templates& t = templates();
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
      {"cli", "--voxel-mask", kNothing, r + "--voxel-mask maybe", 1, "--voxel-mask"},
      {"cli", "--simd", kNothing, r + "--simd maybe", 1, "--simd"},
      {"cli", "--step tiny", kNothing, r + "--step 1e-9", 1, "--step"},
      {"cli", "--step nan", kNothing, r + "--step nan", 1, "--step"},
      {"cli", "--step text", kNothing, r + "--step fast", 2, "--step"},
      {"cli", "--iso nan", kNothing, r + "--iso nan --mode iso", 2, "--iso"},
      {"cli", "--iso-method", kNothing, r + "--mode iso --iso-method guess", 1, "--iso-method"},
      {"cli", "--iso-method without value", kNothing, r + "--mode iso --iso-method", 2, "--iso-method"},
      {"cli", "--filter", kNothing, r + "--filter bicubic", 1, "--filter"},
      {"cli", "--filter out of core with sparseleap", kNothing, r + "--cache-mb 8 --filter cubic", 1, "--filter"},
      {"cli", "--ambient negative", kNothing, r + "--shade --ambient -0.5", 1, "--ambient"},
      {"cli", "--diffuse above one", kNothing, r + "--shade --diffuse 1.5", 1, "--diffuse"},
      {"cli", "--specular nan", kNothing, r + "--shade --specular nan", 1, "--specular"},
      {"cli", "--shininess huge", kNothing, r + "--shade --shininess 1000", 1, "--shininess"},
      {"cli", "--shininess text", kNothing, r + "--shade --shininess shiny", 2, "--shininess"},
      {"cli", "--shade with a value", kNothing, r + "--shade=maybe", 2, "--shade"},
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

TEST(BadInputCorpus, Json) { run_corpus(json_cases()); }

TEST(BadInputCorpus, Cli) { run_corpus(cli_cases()); }

}  // namespace
}  // namespace sl::bad_input
