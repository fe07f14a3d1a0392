#include "client/render/gl.hpp"

#include <string>

namespace grotto::render {

Buffer make_buffer() {
  GLuint n = 0;
  glGenBuffers(1, &n);
  return Buffer(n);
}

VertexArray make_vertex_array() {
  GLuint n = 0;
  glGenVertexArrays(1, &n);
  return VertexArray(n);
}

Texture make_texture() {
  GLuint n = 0;
  glGenTextures(1, &n);
  return Texture(n);
}

Buffer make_static_buffer(GLenum target, const void* data, size_t bytes) {
  Buffer b = make_buffer();
  glBindBuffer(target, b.get());
  glBufferData(target, static_cast<GLsizeiptr>(bytes), data, GL_STATIC_DRAW);
  return b;
}

namespace {

// The stage's source with the defines inserted after its first line (#version must come first).
std::string with_defines(std::string_view source, const std::vector<std::string>& defines) {
  if (defines.empty()) return std::string(source);
  // The #version line is the first non-comment line; insert after it.
  size_t version = source.find("#version");
  size_t eol = version == std::string_view::npos ? 0 : source.find('\n', version);
  if (eol == std::string_view::npos) eol = source.size();
  std::string out(source.substr(0, eol));
  out += '\n';
  for (const std::string& d : defines)
    out += "#define " + d + "\n";
  // Keep line numbers in driver logs meaningful relative to the file after the defines.
  out += source.substr(eol == source.size() ? eol : eol + 1);
  return out;
}

std::string shader_log(GLuint shader) {
  GLint length = 0;
  glGetShaderiv(shader, GL_INFO_LOG_LENGTH, &length);
  std::string log(static_cast<size_t>(length > 0 ? length : 0), '\0');
  if (length > 0) glGetShaderInfoLog(shader, length, nullptr, log.data());
  return log;
}

std::string program_log(GLuint program) {
  GLint length = 0;
  glGetProgramiv(program, GL_INFO_LOG_LENGTH, &length);
  std::string log(static_cast<size_t>(length > 0 ? length : 0), '\0');
  if (length > 0) glGetProgramInfoLog(program, length, nullptr, log.data());
  return log;
}

}  // namespace

Result<Program> Program::build(const std::vector<ShaderStage>& stages,
                               const std::vector<std::string>& defines) {
  std::vector<Shader> shaders;
  for (const ShaderStage& stage : stages) {
    Shader s(glCreateShader(stage.type));
    if (!s) return Error{ErrorCode::kUnavailable, "glCreateShader failed for " + stage.name};
    std::string text = with_defines(stage.source, defines);
    const char* ptr = text.c_str();
    glShaderSource(s.get(), 1, &ptr, nullptr);
    glCompileShader(s.get());
    GLint ok = GL_FALSE;
    glGetShaderiv(s.get(), GL_COMPILE_STATUS, &ok);
    if (ok != GL_TRUE)
      return Error{ErrorCode::kUnavailable,
                   stage.name + " does not compile: " + shader_log(s.get())};
    shaders.push_back(std::move(s));
  }
  Program p;
  p.program_ = GlName<ProgramDeleter>(glCreateProgram());
  for (const Shader& s : shaders)
    glAttachShader(p.program_.get(), s.get());
  glLinkProgram(p.program_.get());
  GLint ok = GL_FALSE;
  glGetProgramiv(p.program_.get(), GL_LINK_STATUS, &ok);
  if (ok != GL_TRUE) {
    std::string names;
    for (const ShaderStage& stage : stages)
      names += (names.empty() ? "" : "+") + stage.name;
    return Error{ErrorCode::kUnavailable,
                 "program " + names + " does not link: " + program_log(p.program_.get())};
  }
  for (const Shader& s : shaders)
    glDetachShader(p.program_.get(), s.get());
  return p;
}

Result<Framebuffer> Framebuffer::create(int width, int height) {
  if (width <= 0 || height <= 0 || width > 16384 || height > 16384)
    return invalid_argument("framebuffer size " + std::to_string(width) + "x" +
                            std::to_string(height) + " is out of range");
  Framebuffer f;
  f.width_ = width;
  f.height_ = height;
  GLuint n = 0;
  glGenFramebuffers(1, &n);
  f.framebuffer_ = FramebufferName(n);
  glGenRenderbuffers(1, &n);
  f.color_ = Renderbuffer(n);
  glGenRenderbuffers(1, &n);
  f.depth_ = Renderbuffer(n);
  glBindRenderbuffer(GL_RENDERBUFFER, f.color_.get());
  glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, width, height);
  glBindRenderbuffer(GL_RENDERBUFFER, f.depth_.get());
  glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT24, width, height);
  glBindFramebuffer(GL_FRAMEBUFFER, f.framebuffer_.get());
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, f.color_.get());
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, f.depth_.get());
  GLenum status = glCheckFramebufferStatus(GL_FRAMEBUFFER);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  if (status != GL_FRAMEBUFFER_COMPLETE)
    return Error{ErrorCode::kUnavailable,
                 "framebuffer incomplete (status 0x" + std::to_string(status) + ")"};
  return f;
}

void Framebuffer::bind() const {
  glBindFramebuffer(GL_FRAMEBUFFER, framebuffer_.get());
  glViewport(0, 0, width_, height_);
}

std::vector<unsigned char> Framebuffer::read_rgb() const {
  std::vector<unsigned char> rgba(static_cast<size_t>(width_) * height_ * 4);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, framebuffer_.get());
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadPixels(0, 0, width_, height_, GL_RGBA, GL_UNSIGNED_BYTE, rgba.data());
  glBindFramebuffer(GL_READ_FRAMEBUFFER, 0);
  std::vector<unsigned char> rgb(static_cast<size_t>(width_) * height_ * 3);
  for (int y = 0; y < height_; ++y) {
    const unsigned char* src = rgba.data() + static_cast<size_t>(height_ - 1 - y) * width_ * 4;
    unsigned char* dst = rgb.data() + static_cast<size_t>(y) * width_ * 3;
    for (int x = 0; x < width_; ++x) {
      dst[3 * x + 0] = src[4 * x + 0];
      dst[3 * x + 1] = src[4 * x + 1];
      dst[3 * x + 2] = src[4 * x + 2];
    }
  }
  return rgb;
}

std::string describe_context() {
  auto str = [](GLenum name) {
    const GLubyte* s = glGetString(name);
    return s ? std::string(reinterpret_cast<const char*>(s)) : std::string("?");
  };
  return "GL " + str(GL_VERSION) + " on " + str(GL_RENDERER);
}

bool context_at_least(int major, int minor) {
  int version = epoxy_gl_version();  // e.g. 45 for 4.5
  return version >= major * 10 + minor;
}

}  // namespace grotto::render
