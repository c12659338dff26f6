// The viewer's window: GLFW with an OpenGL 3.3 core context, Dear ImGui on its GLFW/OpenGL3
// backends, the texture that shows the rendered frame, and reading the window back for screenshots.
// Display only: the volume is rendered by a backend (CPU or CUDA) and uploaded as an image.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

struct GLFWwindow;

namespace sl::viewer {

// No display or no GL 3.3 context: the message is one line saying why and what to do.
class WindowError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class Window {
 public:
  Window(int width, int height, const std::string& title);
  ~Window();
  Window(const Window&) = delete;
  Window& operator=(const Window&) = delete;

  bool should_close() const;
  // Waits for input (or a wake-up from the render worker) at most `timeout` seconds, then starts
  // an ImGui frame. Waiting instead of spinning leaves the cores to the renderer.
  void begin_frame(double timeout_seconds);
  // Draws ImGui over a cleared framebuffer. The back buffer then holds the finished window.
  void end_frame();
  // The back buffer after end_frame, as RGBA8 rows from the bottom (alpha forced to 255).
  std::vector<std::uint8_t> read_back(int& width, int& height) const;
  void swap();

  int framebuffer_width() const;
  int framebuffer_height() const;
  // Framebuffer pixels per window unit (ImGui and mouse coordinates are window units).
  float pixel_ratio() const;
  GLFWwindow* handle() const { return window_; }
  std::string gl_renderer() const;

  // Wakes begin_frame from another thread (the render worker finishing a frame).
  static void wake();

 private:
  GLFWwindow* window_ = nullptr;
};

// The rendered frame as a GL texture (linear filtering: coarse frames are shown stretched).
class FrameTexture {
 public:
  FrameTexture() = default;
  ~FrameTexture();
  FrameTexture(const FrameTexture&) = delete;
  FrameTexture& operator=(const FrameTexture&) = delete;

  void upload(int width, int height, const std::vector<std::uint8_t>& rgba8);
  bool empty() const { return id_ == 0 || width_ == 0; }
  void* imgui_id() const { return reinterpret_cast<void*>(static_cast<std::uintptr_t>(id_)); }
  int width() const { return width_; }
  int height() const { return height_; }

 private:
  unsigned id_ = 0;
  int width_ = 0;
  int height_ = 0;
};

}  // namespace sl::viewer
