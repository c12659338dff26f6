// OpenGL context (DESIGN.md "Layout", gl/): headless through EGL (Mesa's surfaceless platform, no display
// server: CI and render farms) or windowed through GLFW (the viewer). Both end in the same
// initialisation (function loading, version and extension checks, the GlInfo report), so everything
// built on a GlContext (segment-list builder, overlay, display) runs one code path for both.
//
// Function loading uses libepoxy (Debian's libepoxy-dev): it resolves GL entry points lazily through
// whichever of EGL or GLX made the current context, which is exactly the "one code path for two ways
// of getting a context" we need, and it spares us a home-grown loader (STYLE.md, what not to copy).
//
// A context is current on the thread that created it; use it and everything built on it from that
// thread only.
#pragma once

#include <memory>
#include <string>

#include "core/util/error.h"

struct GLFWwindow;

namespace sl {

// No usable context (no EGL/GLX, no GL 4.5 core, missing extensions) or a GL failure (shader
// compilation, out of memory). It is an InputError ("opengl: <reason>") so that apps/ prints it as one
// clear line when a user asks for a GL path on a machine that has none.
class GlError : public InputError {
 public:
  explicit GlError(const std::string& reason) : InputError("opengl", reason) {}
};

struct GlInfo {
  std::string platform;      // "egl-surfaceless", "egl-default" or "glfw"
  std::string vendor;        // GL_VENDOR
  std::string renderer;      // GL_RENDERER, e.g. "llvmpipe (LLVM 15.0.6, 256 bits)"
  std::string version;       // GL_VERSION
  std::string glsl_version;  // GL_SHADING_LANGUAGE_VERSION
  int major = 0;
  int minor = 0;
  bool arb_interlock = false;  // GL_ARB_fragment_shader_interlock (pixel_interlock_ordered)
  bool nv_interlock = false;   // GL_NV_fragment_shader_interlock
  bool interlock() const { return arb_interlock || nv_interlock; }
  std::string summary() const;  // one line: renderer, version, platform, interlock
};

struct GlContextOptions {
  // Requested core-profile version. The builder needs 4.5 (SSBOs, compute, framebuffers without
  // attachments, direct state access); the option exists so tests can ask for the impossible.
  int major = 4;
  int minor = 5;
  bool debug = false;  // debug context; GL errors then carry the driver's message
};

class GlContext {
 public:
  // Headless: EGL surfaceless platform (EGL_MESA_platform_surfaceless), else EGL's default display;
  // a desktop GL core context made current without a surface (EGL_KHR_surfaceless_context).
  // Throws GlError naming the step that failed.
  static std::unique_ptr<GlContext> create_headless(const GlContextOptions& options = {});
  // Windowed: a GLFW window (X11/Wayland) with its context current. Throws GlError with GLFW's reason
  // (e.g. no DISPLAY).
  static std::unique_ptr<GlContext> create_window(int width, int height, const std::string& title,
                                                  bool visible = true, const GlContextOptions& options = {});
  // Headless first; the reason of each failure is kept for the error message. Used by tests and
  // `--lists gl`.
  static std::unique_ptr<GlContext> create_any(const GlContextOptions& options = {});

  ~GlContext();
  GlContext(const GlContext&) = delete;
  GlContext& operator=(const GlContext&) = delete;

  void make_current();
  const GlInfo& info() const;
  GLFWwindow* window() const;  // null when headless
  void swap_buffers();         // windowed only; no-op headless

 private:
  struct Impl;
  explicit GlContext(std::unique_ptr<Impl> impl);
  void finish_init(const GlContextOptions& options);  // the shared part of both ways
  std::unique_ptr<Impl> impl_;
};

// Throws GlError("<what>: GL error 0x.. (<name>)") when glGetError reports one.
void gl_check(const char* what);

}  // namespace sl
