#include "apps/viewer/ui/window.h"

#include <GLFW/glfw3.h>  // includes GL/gl.h: the viewer needs only GL 1.1 calls (textures, read-back)
#include <imgui.h>
#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl3.h>

#include <mutex>

namespace sl::viewer {

namespace {

// GLFW reports why it failed through a callback; the last message goes into the one-line error.
std::mutex g_error_mutex;
std::string g_last_error;

void on_glfw_error(int, const char* description) {
  std::lock_guard lock(g_error_mutex);
  g_last_error = description ? description : "unknown GLFW error";
}

std::string last_error() {
  std::lock_guard lock(g_error_mutex);
  return g_last_error.empty() ? "no reason given" : g_last_error;
}

constexpr const char* kHint =
    " (the viewer needs a display with OpenGL 3.3; on a headless machine run it under Xvfb, e.g. xvfb-run)";

}  // namespace

Window::Window(int width, int height, const std::string& title) {
  glfwSetErrorCallback(on_glfw_error);
  if (!glfwInit()) throw WindowError("cannot open a window: " + last_error() + kHint);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
  glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
  glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
  window_ = glfwCreateWindow(width, height, title.c_str(), nullptr, nullptr);
  if (!window_) {
    const std::string why = last_error();
    glfwTerminate();
    throw WindowError("cannot create an OpenGL 3.3 core window: " + why + kHint);
  }
  glfwMakeContextCurrent(window_);
  glfwSwapInterval(1);

  IMGUI_CHECKVERSION();
  ImGui::CreateContext();
  ImGuiIO& io = ImGui::GetIO();
  io.IniFilename = nullptr;  // no imgui.ini dropped into the user's directory
  ImGui::StyleColorsDark();
  ImGui::GetStyle().WindowRounding = 0.0f;
  if (!ImGui_ImplGlfw_InitForOpenGL(window_, true) || !ImGui_ImplOpenGL3_Init("#version 330 core")) {
    ImGui::DestroyContext();
    glfwDestroyWindow(window_);
    glfwTerminate();
    throw WindowError(std::string("cannot initialise the ImGui OpenGL 3 backend") + kHint);
  }
}

Window::~Window() {
  ImGui_ImplOpenGL3_Shutdown();
  ImGui_ImplGlfw_Shutdown();
  ImGui::DestroyContext();
  glfwDestroyWindow(window_);
  glfwTerminate();
}

bool Window::should_close() const { return glfwWindowShouldClose(window_) != 0; }

void Window::begin_frame(double timeout_seconds) {
  if (timeout_seconds > 0.0) {
    glfwWaitEventsTimeout(timeout_seconds);
  } else {
    glfwPollEvents();
  }
  ImGui_ImplOpenGL3_NewFrame();
  ImGui_ImplGlfw_NewFrame();
  ImGui::NewFrame();
}

void Window::end_frame() {
  ImGui::Render();
  glViewport(0, 0, framebuffer_width(), framebuffer_height());
  glClearColor(0.0f, 0.0f, 0.0f, 1.0f);
  glClear(GL_COLOR_BUFFER_BIT);
  ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
}

std::vector<std::uint8_t> Window::read_back(int& width, int& height) const {
  width = framebuffer_width();
  height = framebuffer_height();
  std::vector<std::uint8_t> px(std::size_t(width) * std::size_t(height) * 4);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadBuffer(GL_BACK);
  glReadPixels(0, 0, width, height, GL_RGBA, GL_UNSIGNED_BYTE, px.data());
  // ImGui blends alpha into the framebuffer too; a screenshot shows what is on screen, opaque.
  for (std::size_t i = 3; i < px.size(); i += 4) px[i] = 255;
  return px;
}

void Window::swap() { glfwSwapBuffers(window_); }

int Window::framebuffer_width() const {
  int w = 0, h = 0;
  glfwGetFramebufferSize(window_, &w, &h);
  return w;
}

int Window::framebuffer_height() const {
  int w = 0, h = 0;
  glfwGetFramebufferSize(window_, &w, &h);
  return h;
}

float Window::pixel_ratio() const {
  int ww = 0, wh = 0;
  glfwGetWindowSize(window_, &ww, &wh);
  return ww > 0 ? float(framebuffer_width()) / float(ww) : 1.0f;
}

std::string Window::gl_renderer() const {
  const auto* r = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  const auto* v = reinterpret_cast<const char*>(glGetString(GL_VERSION));
  return std::string(r ? r : "?") + ", OpenGL " + (v ? v : "?");
}

void Window::wake() { glfwPostEmptyEvent(); }

FrameTexture::~FrameTexture() {
  if (id_) glDeleteTextures(1, &id_);
}

void FrameTexture::upload(int width, int height, const std::vector<std::uint8_t>& rgba8) {
  if (width <= 0 || height <= 0 || rgba8.size() != std::size_t(width) * std::size_t(height) * 4) return;
  if (!id_) {
    glGenTextures(1, &id_);
    glBindTexture(GL_TEXTURE_2D, id_);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  }
  glBindTexture(GL_TEXTURE_2D, id_);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  if (width != width_ || height != height_) {
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, width, height, 0, GL_RGBA, GL_UNSIGNED_BYTE, rgba8.data());
    width_ = width;
    height_ = height;
  } else {
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, width, height, GL_RGBA, GL_UNSIGNED_BYTE, rgba8.data());
  }
}

}  // namespace sl::viewer
