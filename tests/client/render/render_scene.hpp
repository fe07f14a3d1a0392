// The render tests' scene (tests/client/render): one hidden GLFW window with a GL 4.1 core
// context for the whole binary (or the reason why not), the rooms of sector (0,0,0) built with the
// CPU mesh reference and round-tripped through the room codec, and a renderer drawing them into a
// small framebuffer, with the images' measures the tests compare.
#pragma once

#include <GLFW/glfw3.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "client/render/gl.hpp"
#include "client/render/renderer.hpp"
#include "client/render/room_cache.hpp"
#include "common/cave/layout.hpp"
#include "common/codec/room_codec.hpp"
#include "common/mesh/room_mesh.hpp"
#include "tests/client/ready_room.hpp"

namespace grotto::render::test {

constexpr int kWidth = 320;
constexpr int kHeight = 240;
constexpr double kPi = 3.14159265358979323846;

// One hidden GLFW window with a GL 4.1 core context for the whole binary, or the reason why not.
struct GlContext {
  GLFWwindow* window = nullptr;
  std::string why_not;
};

inline GlContext& gl() {
  static GlContext c = [] {
    GlContext out;
    const char* display = std::getenv("DISPLAY");
    if (display == nullptr || *display == '\0') {
      out.why_not = "DISPLAY is not set (run under xvfb-run)";
      return out;
    }
    if (glfwInit() != GLFW_TRUE) {
      out.why_not = std::string("glfwInit failed for DISPLAY=") + display;
      return out;
    }
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 4);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 1);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
    glfwWindowHint(GLFW_VISIBLE, GLFW_FALSE);
    out.window = glfwCreateWindow(64, 64, "render_tests", nullptr, nullptr);
    if (out.window == nullptr) {
      out.why_not = "no OpenGL 4.1 core context on this display";
      return out;
    }
    glfwMakeContextCurrent(out.window);
    std::printf("render_tests: %s\n", describe_context().c_str());
    return out;
  }();
  return c;
}

#define REQUIRE_GL()                                          \
  do {                                                        \
    if (gl().window == nullptr) GTEST_SKIP() << gl().why_not; \
  } while (0)

inline constexpr auto ready = stream::test::ready_room;

// Every room of sector (0,0,0) and its gates, built once for the binary.
// The patch meshes of sector (0,0,0)'s rooms in the world of `seed` (built once per seed).
inline const std::vector<stream::ReadyRoom>& sector_rooms(uint64_t seed = 7) {
  static std::map<uint64_t, std::vector<stream::ReadyRoom>> built;
  if (auto it = built.find(seed); it != built.end()) return it->second;
  const std::vector<stream::ReadyRoom> rooms = [seed] {
    std::vector<stream::ReadyRoom> out;
    const cave::World world = cave::World::create(seed, cave::LayoutParams{}).value();
    const mesh::MeshContext ctx = mesh::MeshContext::create(world, mesh::MeshParams{}).value();
    for (const cave::Room& r : cave::generate_region(world, {0, 0, 0}, {0, 0, 0}).rooms) {
      auto m = mesh::build_room_mesh(ctx, r, mesh::Lod::kPatch);
      EXPECT_TRUE(m.ok()) << r.id.to_string();
      if (m.ok()) out.push_back(ready(m.value(), r));
    }
    return out;
  }();
  return built.emplace(seed, rooms).first->second;
}

struct Image {
  std::vector<unsigned char> rgb;
  int count(unsigned char r, unsigned char g, unsigned char b) const {
    int n = 0;
    for (size_t i = 0; i + 2 < rgb.size(); i += 3)
      n += rgb[i] == r && rgb[i + 1] == g && rgb[i + 2] == b;
    return n;
  }
  double mean_luma() const {
    double sum = 0;
    for (size_t i = 0; i + 2 < rgb.size(); i += 3)
      sum += 0.2126 * rgb[i] + 0.7152 * rgb[i + 1] + 0.0722 * rgb[i + 2];
    return sum / static_cast<double>(rgb.size() / 3);
  }
  int distinct_lumas() const {
    std::array<bool, 256> seen{};
    for (size_t i = 0; i + 2 < rgb.size(); i += 3)
      seen[(rgb[i] + rgb[i + 1] + rgb[i + 2]) / 3] = true;
    return static_cast<int>(std::count(seen.begin(), seen.end(), true));
  }
};

class Scene {
 public:
  explicit Scene(uint64_t seed = 7) {
    auto r = Renderer::create();
    EXPECT_TRUE(r.ok()) << (r.ok() ? "" : r.error().message);
    if (r.ok()) renderer_ = std::make_unique<Renderer>(std::move(r).value());
    auto f = Framebuffer::create(kWidth, kHeight);
    EXPECT_TRUE(f.ok());
    if (f.ok()) framebuffer_ = std::make_unique<Framebuffer>(std::move(f).value());
    for (const stream::ReadyRoom& room : sector_rooms(seed))
      cache_.upload(room);
  }
  bool ok() const { return renderer_ && framebuffer_; }
  const GpuRoomCache& cache() const { return cache_; }

  // Draws one frame; `stats` gets the renderer's counts, `primitives` the triangles the
  // tessellator emitted (GL_PRIMITIVES_GENERATED).
  // Frames are single pictures here: no motion blur (it would smear one pose's picture by the
  // jump from the pose drawn before it).
  // lights: the scene's lights and flares besides the headlamp (Renderer::draw's scene_lights).
  Image draw(const Camera& camera, RenderOptions options, FrameStats* stats = nullptr,
             GLuint* primitives = nullptr, std::span<const Light> lights = {}) {
    options.motion_blur = false;
    framebuffer_->bind();
    GLuint query = 0;
    glGenQueries(1, &query);
    glBeginQuery(GL_PRIMITIVES_GENERATED, query);
    FrameStats s = renderer_->draw(cache_, camera, kWidth, kHeight, options, lights);
    glEndQuery(GL_PRIMITIVES_GENERATED);
    glFinish();
    if (stats != nullptr) *stats = s;
    if (primitives != nullptr) glGetQueryObjectuiv(query, GL_QUERY_RESULT, primitives);
    glDeleteQueries(1, &query);
    Image out{framebuffer_->read_rgb()};
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    return out;
  }

 private:
  std::unique_ptr<Renderer> renderer_;
  std::unique_ptr<Framebuffer> framebuffer_;
  GpuRoomCache cache_;
};

// Interior rooms of the sector, whose centres are in open cave.
inline std::vector<const stream::ReadyRoom*> interior_rooms() {
  std::vector<const stream::ReadyRoom*> out;
  for (const stream::ReadyRoom& r : sector_rooms())
    if (!r.room.id.is_gate()) out.push_back(&r);
  return out;
}

inline Camera camera_in(const stream::ReadyRoom& room, double yaw_deg, double pitch_deg) {
  Camera c;
  c.position = room.room.sphere.centre;
  c.yaw = yaw_deg * kPi / 180;
  c.pitch = pitch_deg * kPi / 180;
  return c;
}

inline int differing_pixels(const Image& a, const Image& b) {
  int n = 0;
  for (size_t i = 0; i + 2 < a.rgb.size() && i + 2 < b.rgb.size(); i += 3)
    n += a.rgb[i] != b.rgb[i] || a.rgb[i + 1] != b.rgb[i + 1] || a.rgb[i + 2] != b.rgb[i + 2];
  return n;
}

// Pixels whose colour differs by more than `threshold` (of 255) in some channel.
inline int pixels_differing_by_more_than(const Image& a, const Image& b, int threshold) {
  int n = 0;
  for (size_t i = 0; i + 2 < a.rgb.size() && i + 2 < b.rgb.size(); i += 3) {
    int most = 0;
    for (size_t c = 0; c < 3; ++c)
      most = std::max(most, std::abs(int{a.rgb[i + c]} - int{b.rgb[i + c]}));
    n += most > threshold;
  }
  return n;
}

}  // namespace grotto::render::test
