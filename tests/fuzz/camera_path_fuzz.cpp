// Camera-path JSON (core/scene/camera_path.cpp), as `bench --path` reads it and `view --record-path`
// writes it: parsed, written back and read back to the same keyframes, and interpolated.
#include "core/scene/camera_path.h"
#include "core/util/error.h"
#include "tests/fuzz/fuzz_util.h"

SL_FUZZ_TARGET(input) {
  const auto parsed = sl::fuzz::accepted([&] { return sl::parse_camera_path(std::string(input), "path.json"); });
  if (!parsed) return;
  const sl::CameraPath& p = *parsed;
  const sl::CameraPath b = sl::parse_camera_path(sl::camera_path_to_json(p), "written");
  if (b.frames != p.frames || b.keyframes.size() != p.keyframes.size()) std::abort();
  for (std::size_t i = 0; i < p.keyframes.size(); ++i) {
    if (b.keyframes[i].eye != p.keyframes[i].eye || b.keyframes[i].center != p.keyframes[i].center) std::abort();
  }
  for (const int i : {0, p.frames / 3, p.frames / 2, p.frames - 1}) p.at(i);
}
