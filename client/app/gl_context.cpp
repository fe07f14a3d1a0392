#include "client/app/gl_context.hpp"

// libepoxy loads libEGL.so.1 when an EGL function is first called, so the window path runs where
// no EGL is installed; <epoxy/egl.h> must come before GLFW's header.
#include <epoxy/egl.h>
// Before <GLFW/glfw3.h>, which GLFW_INCLUDE_NONE keeps from including GL headers of its own.
#include <GLFW/glfw3.h>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <string_view>
#include <utility>
#include <vector>

namespace grotto::app {
namespace {

bool is_set(const char* variable) {
  return variable != nullptr && *variable != '\0';
}

Error unavailable(std::string message) {
  return {ErrorCode::kUnavailable, std::move(message)};
}

// A plain sentence a player can act on instead of a raw GLFW error; a hidden window is a
// headless run that was told to use GLFW.
Error no_display(const std::string& why, bool visible) {
  if (!visible)
    return unavailable("no display (" + why +
                       ") for --gl glfw; leave --gl out or use --gl egl to render without one");
  return unavailable("no display (" + why +
                     "); run it under a desktop session or `xvfb-run -a grotto-client ...`, use "
                     "--screenshot or --bench (they need no display: EGL), or grotto-load for "
                     "headless streaming");
}

// Whether a space-separated extension list names `name` (a whole word, not a prefix).
bool has_extension(const char* list, std::string_view name) {
  if (list == nullptr) return false;
  std::istringstream words{std::string(list)};
  std::string word;
  while (words >> word)
    if (word == name) return true;
  return false;
}

// The last EGL error by name (EGL 1.5 §3.1's codes).
std::string egl_error() {
  const EGLint code = eglGetError();
  switch (code) {
    case EGL_NOT_INITIALIZED:
      return "EGL_NOT_INITIALIZED";
    case EGL_BAD_ACCESS:
      return "EGL_BAD_ACCESS";
    case EGL_BAD_ALLOC:
      return "EGL_BAD_ALLOC";
    case EGL_BAD_ATTRIBUTE:
      return "EGL_BAD_ATTRIBUTE";
    case EGL_BAD_CONFIG:
      return "EGL_BAD_CONFIG";
    case EGL_BAD_CONTEXT:
      return "EGL_BAD_CONTEXT";
    case EGL_BAD_DISPLAY:
      return "EGL_BAD_DISPLAY";
    case EGL_BAD_MATCH:
      return "EGL_BAD_MATCH";
    case EGL_BAD_PARAMETER:
      return "EGL_BAD_PARAMETER";
    default: {
      char text[32];
      std::snprintf(text, sizeof text, "EGL error 0x%04x", static_cast<unsigned>(code));
      return text;
    }
  }
}

// A way to reach an OpenGL implementation through EGL without a window system.
struct EglPlatform {
  EGLenum platform;
  void* native;  // an EGLDeviceEXT, or EGL_DEFAULT_DISPLAY
  std::string origin;
};

// The devices libEGL lists (EGL_EXT_platform_device: the GPUs of NVIDIA's driver and of Mesa's,
// then Mesa's software device, llvmpipe), then Mesa's surfaceless platform.
std::vector<EglPlatform> egl_platforms() {
  const char* client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  std::vector<EglPlatform> gpus, software;
  if (has_extension(client, "EGL_EXT_device_enumeration") &&
      has_extension(client, "EGL_EXT_platform_device")) {
    EGLint count = 0;
    if (eglQueryDevicesEXT(0, nullptr, &count) && count > 0) {
      std::vector<EGLDeviceEXT> devices(static_cast<size_t>(count));
      if (!eglQueryDevicesEXT(count, devices.data(), &count)) count = 0;
      devices.resize(static_cast<size_t>(count));
      for (EGLDeviceEXT device : devices) {
        const char* extensions = eglQueryDeviceStringEXT(device, EGL_EXTENSIONS);
        std::string origin = "EGL device";
        const char* file = has_extension(extensions, "EGL_EXT_device_drm")
                               ? eglQueryDeviceStringEXT(device, EGL_DRM_DEVICE_FILE_EXT)
                               : nullptr;
        if (file != nullptr) origin += std::string(" ") + file;
        const bool is_software = has_extension(extensions, "EGL_MESA_device_software");
        if (is_software) origin += " (software)";
        (is_software ? software : gpus).push_back({EGL_PLATFORM_DEVICE_EXT, device, origin});
      }
    }
  }
  std::vector<EglPlatform> platforms = std::move(gpus);
  platforms.insert(platforms.end(), software.begin(), software.end());
  if (has_extension(client, "EGL_MESA_platform_surfaceless"))
    platforms.push_back({EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, "EGL surfaceless"});
  return platforms;
}

// An OpenGL 4.1 core context on `p` with no surface, made current; on failure `why` says what
// was missing and the display is terminated.
bool open_on(const EglPlatform& p, EGLDisplay& display, EGLContext& context, std::string& why) {
  // Only EGL_EXT_platform_base's entry point: EGL 1.5's eglGetPlatformDisplay takes other types.
  display = eglGetPlatformDisplayEXT(p.platform, p.native, nullptr);
  if (display == EGL_NO_DISPLAY) {
    why = p.origin + ": no display (" + egl_error() + ")";
    return false;
  }
  EGLint major = 0, minor = 0;
  if (!eglInitialize(display, &major, &minor)) {
    why = p.origin + ": cannot initialize (" + egl_error() + ")";
    return false;
  }
  auto fail = [&](const std::string& what) {
    why = p.origin + ": " + what;
    eglTerminate(display);
    return false;
  };
  const char* extensions = eglQueryString(display, EGL_EXTENSIONS);
  if (!has_extension(extensions, "EGL_KHR_surfaceless_context"))
    return fail("no EGL_KHR_surfaceless_context");
  // A core profile of a given version needs EGL 1.5 or EGL_KHR_create_context (same tokens).
  if (major * 10 + minor < 15 && !has_extension(extensions, "EGL_KHR_create_context"))
    return fail("EGL " + std::to_string(major) + "." + std::to_string(minor) +
                " without EGL_KHR_create_context");
  if (!eglBindAPI(EGL_OPENGL_API)) return fail("no desktop OpenGL (" + egl_error() + ")");
  // EGL_SURFACE_TYPE defaults to EGL_WINDOW_BIT, which surfaceless platforms have no config for.
  const EGLint config_attributes[] = {EGL_SURFACE_TYPE, EGL_PBUFFER_BIT, EGL_RENDERABLE_TYPE,
                                      EGL_OPENGL_BIT, EGL_NONE};
  EGLConfig config = nullptr;
  EGLint configs = 0;
  if (!eglChooseConfig(display, config_attributes, &config, 1, &configs) || configs == 0)
    return fail("no config for desktop OpenGL");
  const EGLint context_attributes[] = {EGL_CONTEXT_MAJOR_VERSION_KHR,
                                       4,
                                       EGL_CONTEXT_MINOR_VERSION_KHR,
                                       1,
                                       EGL_CONTEXT_OPENGL_PROFILE_MASK_KHR,
                                       EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT_KHR,
                                       EGL_NONE};
  context = eglCreateContext(display, config, EGL_NO_CONTEXT, context_attributes);
  if (context == EGL_NO_CONTEXT) return fail("no OpenGL 4.1 core context (" + egl_error() + ")");
  if (!eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context)) {
    const std::string error = egl_error();
    eglDestroyContext(display, context);
    return fail("cannot make the context current (" + error + ")");
  }
  return true;
}

}  // namespace

GlBackend choose_backend(const std::string& gl, bool headless, const char* display,
                         const char* wayland) {
  if (!headless || gl == "glfw") return GlBackend::kGlfw;
  if (gl == "egl") return GlBackend::kEgl;
  return is_set(display) || is_set(wayland) ? GlBackend::kGlfw : GlBackend::kEgl;
}

Result<GlContext> GlContext::open_window(int width, int height, bool visible) {
  const char* display = std::getenv("DISPLAY");
  if (!is_set(display) && !is_set(std::getenv("WAYLAND_DISPLAY")))
    return no_display("DISPLAY is not set", visible);
  glfwSetErrorCallback([](int, const char* text) { spdlog::debug("event=glfw_error {}", text); });
  GlContext c;
  if (glfwInit() != GLFW_TRUE)
    return no_display(std::string("cannot open DISPLAY=") + (display ? display : ""), visible);
  c.glfw_initialized_ = true;
  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 4);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 1);
  glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
  glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
  glfwWindowHint(GLFW_VISIBLE, visible ? GLFW_TRUE : GLFW_FALSE);
  c.window_ = glfwCreateWindow(width, height, "grotto-client", nullptr, nullptr);
  if (c.window_ == nullptr)
    return unavailable(
        "this display gives no OpenGL 4.1 core context (the renderer needs tessellation)");
  glfwMakeContextCurrent(c.window_);
  glfwSwapInterval(visible ? 1 : 0);
  c.origin_ = "GLFW";
  return c;
}

Result<GlContext> GlContext::open_egl() {
  if (!epoxy_has_egl())
    return unavailable(
        "no EGL display: libEGL.so.1 cannot be loaded (Debian: libegl1, and libegl-mesa0 or the "
        "GPU's driver)");
  const std::vector<EglPlatform> platforms = egl_platforms();
  if (platforms.empty())
    return unavailable(
        "no EGL display: libEGL lists no device and no Mesa surfaceless platform (install the "
        "GPU's driver, or Debian's libegl-mesa0 for Mesa)");
  std::string reasons;
  for (const EglPlatform& p : platforms) {
    EGLDisplay display = EGL_NO_DISPLAY;
    EGLContext context = EGL_NO_CONTEXT;
    std::string why;
    if (open_on(p, display, context, why)) {
      GlContext c;
      c.backend_ = GlBackend::kEgl;
      c.egl_display_ = display;
      c.egl_context_ = context;
      c.origin_ = p.origin;
      return c;
    }
    spdlog::info("event=egl_skipped {}", why);
    reasons += (reasons.empty() ? "" : "; ") + why;
  }
  return unavailable("EGL gives no OpenGL 4.1 core context (" + reasons + ")");
}

GlContext::GlContext(GlContext&& other) noexcept {
  *this = std::move(other);
}

GlContext& GlContext::operator=(GlContext&& other) noexcept {
  if (this != &other) {
    close();
    backend_ = other.backend_;
    glfw_initialized_ = std::exchange(other.glfw_initialized_, false);
    window_ = std::exchange(other.window_, nullptr);
    egl_display_ = std::exchange(other.egl_display_, nullptr);
    egl_context_ = std::exchange(other.egl_context_, nullptr);
    origin_ = std::move(other.origin_);
  }
  return *this;
}

GlContext::~GlContext() {
  close();
}

void GlContext::close() {
  if (window_ != nullptr) glfwDestroyWindow(std::exchange(window_, nullptr));
  if (std::exchange(glfw_initialized_, false)) glfwTerminate();
  if (egl_display_ != nullptr) {
    EGLDisplay display = std::exchange(egl_display_, nullptr);
    eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    if (egl_context_ != nullptr) eglDestroyContext(display, std::exchange(egl_context_, nullptr));
    eglTerminate(display);
    eglReleaseThread();
  }
}

}  // namespace grotto::app
