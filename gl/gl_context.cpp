#include "gl/gl_context.h"

#include <epoxy/egl.h>
#include <epoxy/gl.h>
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>

#include <cstdio>
#include <cstring>
#include <mutex>

namespace sl {

namespace {

std::string hex(unsigned v) {
  char b[16];
  std::snprintf(b, sizeof b, "0x%04X", v);
  return b;
}

bool has_word(const char* list, const char* word) {
  if (!list) return false;
  const std::size_t n = std::strlen(word);
  for (const char* p = std::strstr(list, word); p; p = std::strstr(p + 1, word)) {
    const bool start = p == list || p[-1] == ' ';
    const bool end = p[n] == '\0' || p[n] == ' ';
    if (start && end) return true;
  }
  return false;
}

// Mesa returns one EGLDisplay per platform; eglTerminate on it would kill every context made from
// it, so live headless contexts are counted and the display is terminated with the last one. GLFW is
// likewise initialised once for all windows.
std::mutex g_mutex;
int g_egl_users = 0;
int g_glfw_users = 0;
std::string g_glfw_error;

void glfw_error(int code, const char* description) {
  g_glfw_error = std::string(description ? description : "unknown") + " (GLFW error " + hex(unsigned(code)) + ")";
}

const char* gl_error_name(GLenum e) {
  switch (e) {
    case GL_INVALID_ENUM: return "GL_INVALID_ENUM";
    case GL_INVALID_VALUE: return "GL_INVALID_VALUE";
    case GL_INVALID_OPERATION: return "GL_INVALID_OPERATION";
    case GL_INVALID_FRAMEBUFFER_OPERATION: return "GL_INVALID_FRAMEBUFFER_OPERATION";
    case GL_OUT_OF_MEMORY: return "GL_OUT_OF_MEMORY";
    default: return "unknown";
  }
}

// libglvnd lets a thread have one current context across EGL and GLX: making a GLX (GLFW) context
// current while an EGL one is fails with BadAccess, and vice versa. Release the other API's first.
// (eglGetCurrentContext is not reliable for this across libglvnd's vendor dispatch: it may answer
// EGL_NO_CONTEXT while Mesa's context is current; eglReleaseThread always releases it.)
void release_egl_context() {
  std::lock_guard<std::mutex> lock(g_mutex);
  if (g_egl_users > 0) eglReleaseThread();
}
void release_glfw_context() {
  std::lock_guard<std::mutex> lock(g_mutex);
  if (g_glfw_users > 0 && glfwGetCurrentContext()) glfwMakeContextCurrent(nullptr);
}

}  // namespace

struct GlContext::Impl {
  GlInfo info;
  EGLDisplay display = EGL_NO_DISPLAY;
  EGLContext context = EGL_NO_CONTEXT;
  GLFWwindow* window = nullptr;

  ~Impl() {
    std::lock_guard<std::mutex> lock(g_mutex);
    if (context != EGL_NO_CONTEXT) {
      eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
      eglDestroyContext(display, context);
    }
    if (display != EGL_NO_DISPLAY && --g_egl_users == 0) {
      eglTerminate(display);
      eglReleaseThread();
    }
    if (window) {
      glfwDestroyWindow(window);
      if (--g_glfw_users == 0) glfwTerminate();
    }
  }
};

std::string GlInfo::summary() const {
  return renderer + " | " + version + " | " + platform + " | interlock: " +
         (arb_interlock ? "ARB" : nv_interlock ? "NV" : "none");
}

GlContext::GlContext(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
GlContext::~GlContext() = default;

std::unique_ptr<GlContext> GlContext::create_headless(const GlContextOptions& options) {
  auto impl = std::make_unique<Impl>();
  {
    std::lock_guard<std::mutex> lock(g_mutex);
    // epoxy_has_egl() dlopens libEGL; without it there is no headless path at all.
    if (!epoxy_has_egl()) throw GlError("no EGL library (install libegl1 and a vendor such as libegl-mesa0)");
    const char* client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
    if (has_word(client, "EGL_MESA_platform_surfaceless") && has_word(client, "EGL_EXT_platform_base")) {
      // The EXT entry point, looked up by hand: epoxy cannot tell before a display exists whether the
      // EGL 1.5 core eglGetPlatformDisplay is there, and the client extension is what Mesa advertises.
      auto get_platform_display = reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(
          eglGetProcAddress("eglGetPlatformDisplayEXT"));
      if (get_platform_display) {
        impl->display = get_platform_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
      }
      impl->info.platform = "egl-surfaceless";
    }
    if (impl->display == EGL_NO_DISPLAY) {  // e.g. NVIDIA's EGL: its default display is headless
      impl->display = eglGetDisplay(EGL_DEFAULT_DISPLAY);
      impl->info.platform = "egl-default";
    }
    if (impl->display == EGL_NO_DISPLAY) throw GlError("EGL: no display (surfaceless platform and default both failed)");
    EGLint maj = 0, min = 0;
    if (!eglInitialize(impl->display, &maj, &min)) {
      impl->display = EGL_NO_DISPLAY;
      throw GlError("EGL: eglInitialize failed (" + hex(unsigned(eglGetError())) + ") on " + impl->info.platform);
    }
    ++g_egl_users;
  }
  const char* ext = eglQueryString(impl->display, EGL_EXTENSIONS);
  if (!has_word(ext, "EGL_KHR_surfaceless_context")) {
    throw GlError("EGL: EGL_KHR_surfaceless_context missing, cannot make a headless context current");
  }
  if (!eglBindAPI(EGL_OPENGL_API)) throw GlError("EGL: desktop OpenGL API not available (eglBindAPI failed)");
  EGLConfig config = EGL_NO_CONFIG_KHR;
  if (!has_word(ext, "EGL_KHR_no_config_context")) {
    const EGLint attrs[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
    EGLint n = 0;
    if (!eglChooseConfig(impl->display, attrs, &config, 1, &n) || n < 1) {
      throw GlError("EGL: no config renders desktop OpenGL");
    }
  }
  const EGLint ctx_attrs[] = {EGL_CONTEXT_MAJOR_VERSION, options.major,
                              EGL_CONTEXT_MINOR_VERSION, options.minor,
                              EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                              EGL_CONTEXT_OPENGL_DEBUG, options.debug ? EGL_TRUE : EGL_FALSE,
                              EGL_NONE};
  impl->context = eglCreateContext(impl->display, config, EGL_NO_CONTEXT, ctx_attrs);
  if (impl->context == EGL_NO_CONTEXT) {
    throw GlError("EGL: cannot create an OpenGL " + std::to_string(options.major) + "." +
                  std::to_string(options.minor) + " core context (" + hex(unsigned(eglGetError())) + ")");
  }
  release_glfw_context();
  if (!eglMakeCurrent(impl->display, EGL_NO_SURFACE, EGL_NO_SURFACE, impl->context)) {
    throw GlError("EGL: eglMakeCurrent without a surface failed (" + hex(unsigned(eglGetError())) + ")");
  }
  std::unique_ptr<GlContext> c(new GlContext(std::move(impl)));
  c->finish_init(options);
  return c;
}

std::unique_ptr<GlContext> GlContext::create_window(int width, int height, const std::string& title, bool visible,
                                                    const GlContextOptions& options) {
  auto impl = std::make_unique<Impl>();
  impl->info.platform = "glfw";
  release_egl_context();  // before glfwCreateWindow, which makes the new context current to query it
  {
    std::lock_guard<std::mutex> lock(g_mutex);
    glfwSetErrorCallback(glfw_error);
    g_glfw_error.clear();
    if (g_glfw_users == 0 && !glfwInit()) throw GlError("GLFW: cannot initialise: " + g_glfw_error);
    ++g_glfw_users;
    glfwDefaultWindowHints();
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, options.major);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, options.minor);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
    glfwWindowHint(GLFW_OPENGL_DEBUG_CONTEXT, options.debug ? GLFW_TRUE : GLFW_FALSE);
    glfwWindowHint(GLFW_VISIBLE, visible ? GLFW_TRUE : GLFW_FALSE);
    impl->window = glfwCreateWindow(width, height, title.c_str(), nullptr, nullptr);
    if (!impl->window) {
      if (--g_glfw_users == 0) glfwTerminate();
      throw GlError("GLFW: cannot create a window with an OpenGL " + std::to_string(options.major) + "." +
                    std::to_string(options.minor) + " core context: " + g_glfw_error);
    }
  }
  glfwMakeContextCurrent(impl->window);
  std::unique_ptr<GlContext> c(new GlContext(std::move(impl)));
  c->finish_init(options);
  return c;
}

std::unique_ptr<GlContext> GlContext::create_any(const GlContextOptions& options) {
  try {
    return create_headless(options);
  } catch (const GlError& headless) {
    try {
      return create_window(16, 16, "sparseleap", false, options);
    } catch (const GlError& windowed) {
      throw GlError("no OpenGL context: headless: " + headless.reason() + "; windowed: " + windowed.reason());
    }
  }
}

// The part both ways share: from here on nothing depends on how the context was made.
void GlContext::finish_init(const GlContextOptions& options) {
  GlInfo& i = impl_->info;
  const int v = epoxy_gl_version();  // e.g. 45; epoxy resolves through EGL or GLX, whichever is current
  i.major = v / 10;
  i.minor = v % 10;
  auto str = [](GLenum e) {
    const GLubyte* s = glGetString(e);
    return s ? std::string(reinterpret_cast<const char*>(s)) : std::string();
  };
  i.vendor = str(GL_VENDOR);
  i.renderer = str(GL_RENDERER);
  i.version = str(GL_VERSION);
  i.glsl_version = str(GL_SHADING_LANGUAGE_VERSION);
  if (!epoxy_is_desktop_gl() || v < options.major * 10 + options.minor) {
    throw GlError("need desktop OpenGL " + std::to_string(options.major) + "." + std::to_string(options.minor) +
                  " core, got '" + i.version + "' (" + i.renderer + ")");
  }
  i.arb_interlock = epoxy_has_gl_extension("GL_ARB_fragment_shader_interlock");
  i.nv_interlock = epoxy_has_gl_extension("GL_NV_fragment_shader_interlock");
  while (glGetError() != GL_NO_ERROR) {
  }
}

void GlContext::make_current() {
  if (impl_->window) {
    release_egl_context();
    glfwMakeContextCurrent(impl_->window);
    return;
  }
  release_glfw_context();
  if (!eglMakeCurrent(impl_->display, EGL_NO_SURFACE, EGL_NO_SURFACE, impl_->context)) {
    throw GlError("EGL: eglMakeCurrent failed (" + hex(unsigned(eglGetError())) + ")");
  }
}

const GlInfo& GlContext::info() const { return impl_->info; }
GLFWwindow* GlContext::window() const { return impl_->window; }
void GlContext::swap_buffers() {
  if (impl_->window) glfwSwapBuffers(impl_->window);
}

void gl_check(const char* what) {
  const GLenum e = glGetError();
  if (e == GL_NO_ERROR) return;
  while (glGetError() != GL_NO_ERROR) {
  }
  throw GlError(std::string(what) + ": GL error " + hex(e) + " (" + gl_error_name(e) + ")");
}

}  // namespace sl
