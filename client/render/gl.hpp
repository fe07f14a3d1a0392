// client/render's thin RAII layer over OpenGL objects (GL 4.1 core through libepoxy). Each wrapper
// owns one GL name, is movable and not copyable, and deletes its name in its destructor; all of
// them need a current context for their whole life, on the thread that made it current.
// Everything that can fail because of the driver (shader compile and link, incomplete
// framebuffers) returns a Result whose message carries the driver's info log.
#pragma once

#include <epoxy/gl.h>

#include <cstdint>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "common/core/result.hpp"

namespace grotto::render {

// Moves a GL name and zeroes the source; Deleter(GLuint) frees a non-zero name.
template <typename Deleter>
class GlName {
 public:
  GlName() = default;
  explicit GlName(GLuint name) : name_(name) {}
  ~GlName() { reset(); }
  GlName(const GlName&) = delete;
  GlName& operator=(const GlName&) = delete;
  GlName(GlName&& other) noexcept : name_(std::exchange(other.name_, 0)) {}
  GlName& operator=(GlName&& other) noexcept {
    if (this != &other) {
      reset();
      name_ = std::exchange(other.name_, 0);
    }
    return *this;
  }
  GLuint get() const { return name_; }
  explicit operator bool() const { return name_ != 0; }
  void reset() {
    if (name_ != 0) Deleter{}(name_);
    name_ = 0;
  }

 private:
  GLuint name_ = 0;
};

struct BufferDeleter {
  void operator()(GLuint n) const { glDeleteBuffers(1, &n); }
};
struct VertexArrayDeleter {
  void operator()(GLuint n) const { glDeleteVertexArrays(1, &n); }
};
struct ProgramDeleter {
  void operator()(GLuint n) const { glDeleteProgram(n); }
};
struct ShaderDeleter {
  void operator()(GLuint n) const { glDeleteShader(n); }
};
struct TextureDeleter {
  void operator()(GLuint n) const { glDeleteTextures(1, &n); }
};
struct RenderbufferDeleter {
  void operator()(GLuint n) const { glDeleteRenderbuffers(1, &n); }
};
struct FramebufferDeleter {
  void operator()(GLuint n) const { glDeleteFramebuffers(1, &n); }
};

struct QueryDeleter {
  void operator()(GLuint n) const { glDeleteQueries(1, &n); }
};

using Buffer = GlName<BufferDeleter>;
using Query = GlName<QueryDeleter>;
using VertexArray = GlName<VertexArrayDeleter>;
using Shader = GlName<ShaderDeleter>;
using Texture = GlName<TextureDeleter>;
using Renderbuffer = GlName<RenderbufferDeleter>;
using FramebufferName = GlName<FramebufferDeleter>;

Buffer make_buffer();
VertexArray make_vertex_array();
Texture make_texture();

// A buffer filled with `bytes` bytes from `data` (GL_STATIC_DRAW), bound to `target` on return.
Buffer make_static_buffer(GLenum target, const void* data, size_t bytes);

// One stage's source; `defines` lines ("NAME VALUE") go after its #version line.
struct ShaderStage {
  GLenum type = GL_VERTEX_SHADER;
  std::string_view source;
  std::string name;  // for error messages: "room.tese"
};

// A linked program. Uniform locations are looked up by name and cached by the caller.
class Program {
 public:
  Program() = default;
  // Compiles and links the stages; errors carry the stage name and the driver's info log.
  static Result<Program> build(const std::vector<ShaderStage>& stages,
                               const std::vector<std::string>& defines = {});
  GLuint get() const { return program_.get(); }
  GLint uniform(const char* name) const { return glGetUniformLocation(program_.get(), name); }
  void use() const { glUseProgram(program_.get()); }

 private:
  GlName<ProgramDeleter> program_;
};

// An offscreen RGBA8 colour + depth target, for headless screenshots and tests.
class Framebuffer {
 public:
  Framebuffer() = default;
  static Result<Framebuffer> create(int width, int height);
  void bind() const;  // also sets the viewport
  int width() const { return width_; }
  int height() const { return height_; }
  // Reads the colour attachment as RGB rows, top row first (the PNG order).
  std::vector<unsigned char> read_rgb() const;

 private:
  FramebufferName framebuffer_;
  Renderbuffer color_;
  Renderbuffer depth_;
  int width_ = 0;
  int height_ = 0;
};

// The GL version and renderer strings of the current context, for logs.
std::string describe_context();
// True when the current context is at least `major`.`minor`.
bool context_at_least(int major, int minor);

}  // namespace grotto::render
