#include "gl/gl_program.h"

#include <stdexcept>
#include <vector>

#include "gl/gl_context.h"
#include "gl/shaders_embedded.h"

namespace sl {

std::string_view glsl_file(std::string_view name) {
  for (const glsl::File& f : glsl::kFiles) {
    if (name == f.name) return f.text;
  }
  throw std::out_of_range("no embedded GLSL file '" + std::string(name) + "'");
}

std::string assemble_glsl(std::string_view preamble, std::initializer_list<std::string_view> files) {
  std::string s = "#version 450 core\n";
  s += preamble;
  if (!s.empty() && s.back() != '\n') s += '\n';
  int index = 1;
  for (std::string_view f : files) {
    // #line <line> <source string number>: messages read "<index>:<line>", index = position in `files`.
    s += "#line 1 " + std::to_string(index++) + "\n";
    s += glsl_file(f);
    s += '\n';
  }
  return s;
}

GlBuffer::~GlBuffer() {
  if (id_) glDeleteBuffers(1, &id_);
}

GlBuffer& GlBuffer::operator=(GlBuffer&& o) noexcept {
  if (this != &o) {
    if (id_) glDeleteBuffers(1, &id_);
    id_ = std::exchange(o.id_, 0u);
    bytes_ = std::exchange(o.bytes_, 0u);
  }
  return *this;
}

void GlBuffer::allocate(std::size_t bytes, GLenum usage) {
  bytes = bytes < 16 ? 16 : bytes;
  if (id_ && bytes_ == bytes) return;
  if (!id_) glCreateBuffers(1, &id_);
  glNamedBufferData(id_, GLsizeiptr(bytes), nullptr, usage);
  if (glGetError() == GL_OUT_OF_MEMORY) {
    throw GlError("out of memory allocating a buffer of " + std::to_string(bytes) + " bytes");
  }
  bytes_ = bytes;
}

void GlBuffer::reserve(std::size_t bytes, GLenum usage) {
  if (!id_ || bytes > bytes_) allocate(bytes, usage);
}

void GlBuffer::upload(const void* data, std::size_t bytes, GLenum usage) {
  allocate(bytes, usage);
  if (bytes > 0) glNamedBufferSubData(id_, 0, GLsizeiptr(bytes), data);
}

void GlBuffer::read(std::size_t offset, std::size_t bytes, void* out) const {
  if (bytes > 0) glGetNamedBufferSubData(id_, GLintptr(offset), GLsizeiptr(bytes), out);
}

void GlBuffer::clear_u32(std::size_t offset, std::size_t bytes, std::uint32_t value) {
  if (bytes > 0) {
    glClearNamedBufferSubData(id_, GL_R32UI, GLintptr(offset), GLsizeiptr(bytes), GL_RED_INTEGER, GL_UNSIGNED_INT,
                              &value);
  }
}

void GlBuffer::bind_range(GLuint index, std::size_t offset, std::size_t bytes) const {
  glBindBufferRange(GL_SHADER_STORAGE_BUFFER, index, id_, GLintptr(offset), GLsizeiptr(bytes));
}

namespace {

// The info log of a shader or a program: the same two calls, with the getters of its kind.
template <class GetIv, class GetLog>
std::string info_log(GLuint object, GetIv get_iv, GetLog get_log) {
  GLint n = 0;
  get_iv(object, GL_INFO_LOG_LENGTH, &n);
  std::vector<char> log(std::size_t(n > 0 ? n : 1), '\0');
  get_log(object, GLsizei(log.size()), nullptr, log.data());
  return log.data();
}

std::string shader_log(GLuint s) { return info_log(s, glGetShaderiv, glGetShaderInfoLog); }
std::string program_log(GLuint p) { return info_log(p, glGetProgramiv, glGetProgramInfoLog); }

}  // namespace

GlProgram::GlProgram(const std::string& name, std::initializer_list<std::pair<GLenum, std::string>> stages) {
  id_ = glCreateProgram();
  std::vector<GLuint> shaders;
  auto cleanup = [&] {
    for (GLuint s : shaders) glDeleteShader(s);
  };
  for (const auto& [type, source] : stages) {
    const GLuint s = glCreateShader(type);
    shaders.push_back(s);
    const char* src = source.c_str();
    glShaderSource(s, 1, &src, nullptr);
    glCompileShader(s);
    GLint ok = GL_FALSE;
    glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
    if (!ok) {
      const std::string log = shader_log(s);
      cleanup();
      throw GlError("cannot compile " + name + ": " + log);
    }
    glAttachShader(id_, s);
  }
  glLinkProgram(id_);
  cleanup();
  GLint ok = GL_FALSE;
  glGetProgramiv(id_, GL_LINK_STATUS, &ok);
  if (!ok) throw GlError("cannot link " + name + ": " + program_log(id_));
}

GlProgram::~GlProgram() {
  if (id_) glDeleteProgram(id_);
}

GlProgram& GlProgram::operator=(GlProgram&& o) noexcept {
  if (this != &o) {
    if (id_) glDeleteProgram(id_);
    id_ = std::exchange(o.id_, 0u);
  }
  return *this;
}

GlDrawTarget::GlDrawTarget() {
  glCreateVertexArrays(1, &vao_);
  glCreateFramebuffers(1, &fbo_);
}

GlDrawTarget::~GlDrawTarget() {
  glDeleteFramebuffers(1, &fbo_);
  glDeleteVertexArrays(1, &vao_);
}

void GlDrawTarget::bind(int width, int height) {
  if (width != width_ || height != height_) {
    glNamedFramebufferParameteri(fbo_, GL_FRAMEBUFFER_DEFAULT_WIDTH, width);
    glNamedFramebufferParameteri(fbo_, GL_FRAMEBUFFER_DEFAULT_HEIGHT, height);
    width_ = width;
    height_ = height;
  }
  glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
  glBindVertexArray(vao_);
  glViewport(0, 0, width, height);
}

}  // namespace sl
