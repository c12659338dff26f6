#include "apps/viewer/path_recorder.h"

#include <cmath>

#include "apps/viewer/view_settings.h"
#include "core/util/atomic_file.h"
#include "core/util/error.h"

namespace sl::viewer {

bool PathRecorder::add(const Camera& c) {
  if (!path_.keyframes.empty() && same_camera(path_.keyframes.back(), c)) return false;
  path_.keyframes.push_back(c);
  return true;
}

void PathRecorder::set_interval(double seconds) {
  interval_ = std::isfinite(seconds) && seconds > 0.0 ? seconds : 0.0;
  last_tick_ = -1.0;  // the first tick after switching on records at once
}

bool PathRecorder::tick(double now, const Camera& c) {
  if (interval_ <= 0.0) return false;
  if (last_tick_ >= 0.0 && now - last_tick_ < interval_) return false;
  last_tick_ = now;
  return add(c);
}

void PathRecorder::clear() {
  path_.keyframes.clear();
  last_tick_ = -1.0;
}

CameraPath PathRecorder::path() const {
  CameraPath p = path_;
  const int n = int(p.keyframes.size());
  p.frames = n <= 1 ? 1 : (n - 1) * frames_per_segment_ + 1;
  return p;
}

void PathRecorder::save(const std::string& file) const {
  if (path_.keyframes.empty()) throw InputError(file, "no keyframes recorded (press K, or turn on the timer)");
  write_file_atomic(file, to_json() + "\n");
}

}  // namespace sl::viewer
