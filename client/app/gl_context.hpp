// The OpenGL 4.1 core context grotto-client draws with, made one of two ways: a GLFW window (the
// interactive window, or a hidden one for --screenshot and --bench under an X server), or EGL
// with no window system at all (--screenshot and --bench on a GPU box or in a container without
// X). Headless runs draw into their own framebuffer object, so an EGL context needs no surface.
#pragma once

#include <string>

#include "common/core/result.hpp"

struct GLFWwindow;

namespace grotto::app {

enum class GlBackend { kGlfw, kEgl };

// --gl: "glfw", "egl" or "auto". The window always takes GLFW; auto gives headless runs GLFW
// where DISPLAY or WAYLAND_DISPLAY is set and EGL otherwise. `display` and `wayland` are those
// variables (null when unset). The caller has checked that `gl` is one of the three.
GlBackend choose_backend(const std::string& gl, bool headless, const char* display,
                         const char* wayland);

// Owns the context and what it needs (GLFW's library state, or the EGL display) and makes the
// context current on the calling thread when created; every GL object must be released before it
// is destroyed. Movable, not copyable. Errors are one sentence for the user, without a prefix.
class GlContext {
 public:
  // A GLFW window of width x height with a current context; hidden windows are for headless runs
  // (they draw into framebuffer objects) and swap without waiting for vertical sync.
  static Result<GlContext> open_window(int width, int height, bool visible);
  // A context with no surface and no window system, current on this thread: on an EGL device
  // (eglQueryDevicesEXT; a GPU's before Mesa's software device), else on Mesa's surfaceless
  // platform. It has no default framebuffer.
  static Result<GlContext> open_egl();

  GlContext(GlContext&& other) noexcept;
  GlContext& operator=(GlContext&& other) noexcept;
  GlContext(const GlContext&) = delete;
  GlContext& operator=(const GlContext&) = delete;
  ~GlContext();

  GlBackend backend() const { return backend_; }
  // The GLFW window; null for EGL.
  GLFWwindow* window() const { return window_; }
  // Where the context came from, for the log: "GLFW", "EGL device /dev/dri/card1", "EGL device
  // (software)" (Mesa's llvmpipe) or "EGL surfaceless".
  const std::string& origin() const { return origin_; }

 private:
  GlContext() = default;
  void close();

  GlBackend backend_ = GlBackend::kGlfw;
  bool glfw_initialized_ = false;
  GLFWwindow* window_ = nullptr;
  void* egl_display_ = nullptr;  // EGLDisplay and EGLContext, kept opaque to keep <EGL/egl.h>
  void* egl_context_ = nullptr;  // out of this header
  std::string origin_;
};

}  // namespace grotto::app
