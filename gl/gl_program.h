// Small owners of GL objects (buffers, programs, vertex arrays, framebuffers) and the assembly of the
// embedded GLSL sources (gl/shaders/, compiled into the library by gl/CMakeLists.txt). GL calls need a
// current GlContext.
#pragma once

#include <epoxy/gl.h>

#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <string>
#include <string_view>
#include <utility>

namespace sl {

// The embedded shader files by name ("common.glsl", "segment_list.glsl", "rect.vert", ...). Throws
// std::out_of_range for an unknown name.
std::string_view glsl_file(std::string_view name);

// "#version 450 core", then `preamble` (extensions, #defines), then the named files in order, each
// preceded by a #line directive so compiler messages point into the right file.
std::string assemble_glsl(std::string_view preamble, std::initializer_list<std::string_view> files);

class GlBuffer {
 public:
  GlBuffer() = default;
  ~GlBuffer();
  GlBuffer(GlBuffer&& o) noexcept : id_(std::exchange(o.id_, 0u)), bytes_(std::exchange(o.bytes_, 0u)) {}
  GlBuffer& operator=(GlBuffer&& o) noexcept;
  GlBuffer(const GlBuffer&) = delete;
  GlBuffer& operator=(const GlBuffer&) = delete;

  // (Re)allocates to `bytes` (at least 16, contents undefined) unless it already has that size.
  void allocate(std::size_t bytes, GLenum usage = GL_DYNAMIC_DRAW);
  // Grows to hold at least `bytes`; contents are lost when it grows.
  void reserve(std::size_t bytes, GLenum usage = GL_DYNAMIC_DRAW);
  // Allocates exactly what `data` needs (at least 16 bytes) and uploads it.
  void upload(const void* data, std::size_t bytes, GLenum usage = GL_DYNAMIC_DRAW);
  void read(std::size_t offset, std::size_t bytes, void* out) const;
  void clear_u32(std::size_t offset, std::size_t bytes, std::uint32_t value);
  // Binds [offset, offset + bytes) to shader-storage binding `index`.
  void bind_range(GLuint index, std::size_t offset, std::size_t bytes) const;
  void bind(GLuint index) const { bind_range(index, 0, bytes_); }

  GLuint id() const { return id_; }
  std::size_t bytes() const { return bytes_; }

 private:
  GLuint id_ = 0;
  std::size_t bytes_ = 0;
};

class GlProgram {
 public:
  GlProgram() = default;
  // Compiles and links; throws GlError with the driver's log and `name` on failure.
  GlProgram(const std::string& name, std::initializer_list<std::pair<GLenum, std::string>> stages);
  ~GlProgram();
  GlProgram(GlProgram&& o) noexcept : id_(std::exchange(o.id_, 0u)) {}
  GlProgram& operator=(GlProgram&& o) noexcept;
  GlProgram(const GlProgram&) = delete;
  GlProgram& operator=(const GlProgram&) = delete;

  GLuint id() const { return id_; }
  // Location of a uniform, -1 when the compiler removed it (setting -1 is a no-op in GL).
  GLint uniform(const char* name) const { return glGetUniformLocation(id_, name); }

 private:
  GLuint id_ = 0;
};

// A vertex array with no attributes (core profile needs one bound to draw) and a framebuffer without
// attachments of a given size (rasterization with nothing to write but SSBOs).
class GlDrawTarget {
 public:
  GlDrawTarget();
  ~GlDrawTarget();
  GlDrawTarget(const GlDrawTarget&) = delete;
  GlDrawTarget& operator=(const GlDrawTarget&) = delete;
  void bind(int width, int height);

 private:
  GLuint vao_ = 0;
  GLuint fbo_ = 0;
  int width_ = 0;
  int height_ = 0;
};

}  // namespace sl
