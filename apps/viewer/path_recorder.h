// Recording the viewer's camera as a keyframe path that `sparseleap bench --path` replays
// (core/scene/camera_path.h format): a keyframe each time the user presses K, or on a timer.
#pragma once

#include <string>

#include "core/scene/camera_path.h"

namespace sl::viewer {

class PathRecorder {
 public:
  // Frames that `bench` renders between two consecutive keyframes.
  explicit PathRecorder(int frames_per_segment = 30)
      : frames_per_segment_(frames_per_segment < 1 ? 1 : frames_per_segment) {}

  // Appends a keyframe; false (nothing added) when it equals the last one, so holding K or an idle
  // timer does not pile up identical keyframes that would stall the replayed path.
  bool add(const Camera& c);
  // 0 turns the timer off. While on, tick() adds a keyframe every `seconds`.
  void set_interval(double seconds);
  double interval() const { return interval_; }
  // Called once per UI frame with the current time; returns whether a keyframe was added.
  bool tick(double now_seconds, const Camera& c);
  void clear();

  std::size_t size() const { return path_.keyframes.size(); }
  int frames_per_segment() const { return frames_per_segment_; }
  void set_frames_per_segment(int n) { frames_per_segment_ = n < 1 ? 1 : n; }
  // The recorded path: frames = (keyframes - 1) * frames_per_segment + 1 (one frame per keyframe
  // when only one was recorded).
  CameraPath path() const;
  std::string to_json() const { return camera_path_to_json(path()); }
  // InputError(file, ...) when nothing was recorded or the file cannot be written.
  void save(const std::string& file) const;

 private:
  CameraPath path_;
  int frames_per_segment_ = 30;
  double interval_ = 0.0;
  double last_tick_ = -1.0;
};

}  // namespace sl::viewer
