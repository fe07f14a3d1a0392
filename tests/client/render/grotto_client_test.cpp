// The grotto-client program: --help, the plain sentence without a display, and a headless
// screenshot against its in-process server (CPU reference). Runs under xvfb-run with the other
// render tests; the screenshot test skips where the display gives no GL 4.1 context.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "common/cave/layout.hpp"
#include "common/core/vec3.hpp"
#include "common/mesh/room_mesh.hpp"
#include "common/png/png.hpp"
#include "common/relief/relief.hpp"

namespace {

struct Outcome {
  int status = -1;
  std::string output;
};

Outcome run(const std::string& command) {
  Outcome r;
  FILE* pipe = popen((command + " 2>&1").c_str(), "r");
  if (pipe == nullptr) return r;
  std::array<char, 4096> buffer{};
  size_t n = 0;
  while ((n = fread(buffer.data(), 1, buffer.size(), pipe)) > 0)
    r.output.append(buffer.data(), n);
  int status = pclose(pipe);
  r.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

// The pixels of a PNG grotto-client wrote (empty when it is missing or unreadable).
std::vector<unsigned char> read_picture(const std::string& path, int& width, int& height) {
  auto image = grotto::png::read_png(path);
  if (!image) return {};
  width = image.value().width;
  height = image.value().height;
  return std::move(image).value().rgb;
}

TEST(GrottoClient, help_describes_every_option) {
  Outcome r = run(std::string(GROTTO_CLIENT_BIN) + " --help");
  EXPECT_EQ(r.status, 0) << r.output;
  for (const char* option :
       {"--server",         "--seed",     "--device",    "--width",        "--height",
        "--tess-max",       "--no-tess",  "--wireframe", "--surface",      "--screenshot",
        "--frames",         "--pose",     "--wait",      "room:<id>",      "--no-bloom",
        "--no-motion-blur", "--exposure", "B: bloom",    "M: motion blur", "--gl"})
    EXPECT_NE(r.output.find(option), std::string::npos) << option;
}

TEST(GrottoClient, a_bad_flag_exits_2_naming_it) {
  for (const char* args :
       {"--no-such-flag", "--width 3", "--surface bumpy", "--pose 1,2", "--pose room:1.2.banana",
        "--exposure 0", "--mode swim", "--gl vulkan", "--gl egl"}) {
    Outcome r = run(std::string(GROTTO_CLIENT_BIN) + " " + args);
    EXPECT_EQ(r.status, 2) << args << " said: " << r.output;
    const std::string flag = std::string(args).substr(0, std::string(args).find(' '));
    EXPECT_NE(r.output.find(flag), std::string::npos) << args << " said: " << r.output;
  }
}

TEST(GrottoClient, without_a_display_says_so_plainly) {
  Outcome r = run(std::string("env -u DISPLAY -u WAYLAND_DISPLAY ") + GROTTO_CLIENT_BIN);
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_EQ(r.output,
            "grotto-client: no display (DISPLAY is not set); run it under a desktop session or "
            "`xvfb-run -a grotto-client ...`, use --screenshot or --bench (they need no display: "
            "EGL), or grotto-load for headless streaming\n");
  // A headless run told to use GLFW needs a display too.
  Outcome glfw = run(std::string("env -u DISPLAY -u WAYLAND_DISPLAY ") + GROTTO_CLIENT_BIN +
                     " --gl glfw --screenshot never.png");
  EXPECT_EQ(glfw.status, 1) << glfw.output;
  EXPECT_EQ(glfw.output.rfind("grotto-client: no display (DISPLAY is not set)", 0), 0u)
      << glfw.output;
  EXPECT_FALSE(std::filesystem::exists("never.png"));
}

// The share of pixels brighter than the dark beyond the lamp (grotto-client's own test for a
// screenshot that shows the cave, app.cpp).
double lit_fraction(const std::vector<unsigned char>& rgb) {
  size_t lit = 0;
  for (size_t i = 0; i + 2 < rgb.size(); i += 3)
    lit += std::max({rgb[i], rgb[i + 1], rgb[i + 2]}) > 12;
  return rgb.empty() ? 0 : static_cast<double>(lit) / static_cast<double>(rgb.size() / 3);
}

// On a machine with no X server (a GPU box, a container) --screenshot and --bench make
// their context with EGL and no window system. Here that is Mesa's llvmpipe through EGL's
// software device or surfaceless platform; the picture is the same kind as under Xvfb.
TEST(GrottoClient, without_a_display_a_screenshot_renders_through_egl) {
  const std::string path =
      (std::filesystem::temp_directory_path() / "grotto_client_test_egl.png").string();
  std::filesystem::remove(path);
  Outcome r = run(std::string("env -u DISPLAY -u WAYLAND_DISPLAY ") + GROTTO_CLIENT_BIN +
                  " --device none --seed 7 --width 320 --height 180 --tess-max 4 --frames 2" +
                  " --wait 120 --flythrough 3 --log-level info --screenshot " + path);
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("event=gl_context backend=egl"), std::string::npos) << r.output;
  int width = 0, height = 0;
  std::vector<unsigned char> rgb = read_picture(path, width, height);
  ASSERT_EQ(width, 320);
  ASSERT_EQ(height, 180);
  ASSERT_EQ(rgb.size(), 320u * 180u * 3u);
  EXPECT_GT(lit_fraction(rgb), 0.5) << "the EGL screenshot is mostly dark";
  std::filesystem::remove(path);
}

// --bench on a GPU box with no X server: the same path through EGL, and the report names what drew.
TEST(GrottoClient, without_a_display_bench_measures_through_egl) {
  const std::string path =
      (std::filesystem::temp_directory_path() / "grotto_client_test_egl_bench.json").string();
  std::filesystem::remove(path);
  Outcome r = run(std::string("env -u DISPLAY -u WAYLAND_DISPLAY ") + GROTTO_CLIENT_BIN +
                  " --device none --seed 7 --width 160 --height 90 --tess-max 4 --wait 120" +
                  " --bench 1 --json " + path);
  ASSERT_EQ(r.status, 0) << r.output;
  std::ifstream f(path);
  const nlohmann::json j = nlohmann::json::parse(f, nullptr, false);
  ASSERT_FALSE(j.is_discarded()) << "invalid JSON in " << path;
  EXPECT_GT(j.value("frames", 0), 0);
  EXPECT_NE(j.value("gl_renderer", std::string("unknown")), "unknown");
  std::filesystem::remove(path);
}

// Without a usable EGL (here: libEGL finds no vendor library) a headless run fails at once with
// one line and writes nothing: a screenshot that shows nothing is a failure.
TEST(GrottoClient, without_egl_a_headless_run_fails_with_one_line) {
  const std::string path =
      (std::filesystem::temp_directory_path() / "grotto_client_test_no_egl.png").string();
  std::filesystem::remove(path);
  Outcome r = run(std::string("env -u DISPLAY -u WAYLAND_DISPLAY "
                              "__EGL_VENDOR_LIBRARY_FILENAMES=/nonexistent.json ") +
                  GROTTO_CLIENT_BIN + " --gl egl --device none --screenshot " + path);
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_EQ(r.output.rfind("grotto-client: ", 0), 0u) << r.output;
  EXPECT_NE(r.output.find("EGL"), std::string::npos) << r.output;
  EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  EXPECT_FALSE(std::filesystem::exists(path));
}

TEST(GrottoClient, screenshot_writes_a_picture_of_the_spawn_room) {
  const char* display = std::getenv("DISPLAY");
  if (display == nullptr || *display == '\0') GTEST_SKIP() << "DISPLAY is not set";
  const std::string path =
      (std::filesystem::temp_directory_path() / "grotto_client_test_screenshot.png").string();
  std::filesystem::remove(path);
  Outcome r =
      run(std::string(GROTTO_CLIENT_BIN) + " --device none --seed 7 --width 320 --height 240" +
          " --tess-max 8 --frames 3 --wait 120 --screenshot " + path);
  if (r.output.find("no OpenGL 4.1") != std::string::npos) GTEST_SKIP() << r.output;
  ASSERT_EQ(r.status, 0) << r.output;
  int width = 0, height = 0;
  std::vector<unsigned char> rgb = read_picture(path, width, height);
  ASSERT_EQ(width, 320);
  ASSERT_EQ(height, 240);
  ASSERT_EQ(rgb.size(), 320u * 240u * 3u);
  int differing = 0;
  for (size_t i = 3; i < rgb.size(); i += 3)
    differing += rgb[i] != rgb[0] || rgb[i + 1] != rgb[1];
  EXPECT_GT(differing, 320 * 240 / 4) << "the screenshot is nearly one colour";
  std::filesystem::remove(path);
}

// The player and the scripted path (client/play): flags, --bench's statistics and JSON, and a
// screenshot along the flythrough. Small frames and tess 4: llvmpipe is slow.
TEST(GrottoClient, help_describes_the_player_and_bench_options) {
  Outcome r = run(std::string(GROTTO_CLIENT_BIN) + " --help");
  EXPECT_EQ(r.status, 0) << r.output;
  for (const char* option : {"--mode", "--flythrough", "--bench", "--json", "--speed",
                             "G: walk/fly", "N: noclip", "Space: jump"})
    EXPECT_NE(r.output.find(option), std::string::npos) << option;
}

TEST(GrottoClient, an_invalid_mode_or_bench_time_is_refused_naming_the_flag) {
  const std::string bin = GROTTO_CLIENT_BIN;
  Outcome mode = run(bin + " --mode run");
  EXPECT_EQ(mode.status, 2);
  EXPECT_EQ(mode.output, "grotto-client: --mode must be walk or fly (got 'run')\n");
  for (const char* bench : {" --bench -1", " --bench=-2.5", " --bench 0"}) {
    Outcome r = run(bin + bench);
    EXPECT_EQ(r.status, 2) << bench;
    EXPECT_NE(r.output.find("--bench must be a number of seconds in (0, 3600]"), std::string::npos)
        << r.output;
  }
  Outcome json = run(bin + " --json x.json");
  EXPECT_EQ(json.status, 2);
  EXPECT_NE(json.output.find("--json needs --bench or --screenshot"), std::string::npos)
      << json.output;
  Outcome fly = run(bin + " --flythrough -1");
  EXPECT_EQ(fly.status, 2);
  EXPECT_NE(fly.output.find("--flythrough must be"), std::string::npos) << fly.output;
}

TEST(GrottoClient, bench_prints_frame_time_statistics_and_writes_them_as_json) {
  const char* display = std::getenv("DISPLAY");
  if (display == nullptr || *display == '\0') GTEST_SKIP() << "DISPLAY is not set";
  const std::string path =
      (std::filesystem::temp_directory_path() / "grotto_client_test_bench.json").string();
  std::filesystem::remove(path);
  Outcome r = run(std::string(GROTTO_CLIENT_BIN) +
                  " --device none --seed 7 --width 320 --height 180 --tess-max 4 --wait 120" +
                  " --bench 2 --json " + path);
  if (r.output.find("no OpenGL 4.1") != std::string::npos) GTEST_SKIP() << r.output;
  ASSERT_EQ(r.status, 0) << r.output;
  for (const char* field :
       {"grotto-client bench: ", " frames in ", "mean ", "median ", "p95 ", "p99 ", "max ", " fps"})
    EXPECT_NE(r.output.find(field), std::string::npos) << field << " in " << r.output;
  std::ifstream f(path);
  const nlohmann::json j = nlohmann::json::parse(f, nullptr, false);
  ASSERT_FALSE(j.is_discarded()) << "invalid JSON in " << path;
  for (const char* key : {"frames", "seconds", "mean_ms", "median_ms", "p95_ms", "p99_ms", "max_ms",
                          "fps", "rooms_loaded", "path_length_m"})
    ASSERT_TRUE(j.contains(key) && j[key].is_number()) << key;
  EXPECT_GT(j["frames"].get<int>(), 0);
  EXPECT_GE(j["seconds"].get<double>(), 2.0);
  EXPECT_LE(j["median_ms"].get<double>(), j["p95_ms"].get<double>());
  EXPECT_LE(j["p95_ms"].get<double>(), j["p99_ms"].get<double>());
  EXPECT_LE(j["p99_ms"].get<double>(), j["max_ms"].get<double>());
  EXPECT_GT(j["path_length_m"].get<double>(), 5.0);
  // The report says what drew the frames.
  ASSERT_TRUE(j.contains("gl_renderer") && j["gl_renderer"].is_string());
  EXPECT_NE(j["gl_renderer"].get<std::string>(), "unknown");
  EXPECT_TRUE(j.contains("gl_version") && j["gl_version"].is_string());
  EXPECT_TRUE(j.value("relief", false));
  std::filesystem::remove(path);
}

// --pose room:<id> starts inside that room; a pose in solid rock fails with the reason, writing
// no picture.
TEST(GrottoClient, a_room_pose_starts_inside_the_room_and_a_pose_in_rock_fails_plainly) {
  const char* display = std::getenv("DISPLAY");
  if (display == nullptr || *display == '\0') GTEST_SKIP() << "DISPLAY is not set";
  const std::string path =
      (std::filesystem::temp_directory_path() / "grotto_client_test_room_pose.png").string();
  std::filesystem::remove(path);
  const std::string base = std::string(GROTTO_CLIENT_BIN) +
                           " --device none --width 240 --height 160 --tess-max 4 --frames 2"
                           " --screenshot " +
                           path;
  Outcome r = run(base + " --wait 120 --pose room:0.0.0.r2");
  if (r.output.find("no OpenGL 4.1") != std::string::npos) GTEST_SKIP() << r.output;
  ASSERT_EQ(r.status, 0) << r.output;
  int width = 0, height = 0;
  std::vector<unsigned char> rgb = read_picture(path, width, height);
  ASSERT_EQ(rgb.size(), 240u * 160u * 3u);
  std::filesystem::remove(path);

  // Far below the cave's sectors' rooms: solid rock.
  Outcome rock = run(base + " --wait 5 --pose 0.5,-3000.5,0.5");
  EXPECT_EQ(rock.status, 1) << rock.output;
  EXPECT_NE(rock.output.find("grotto-client: --screenshot: "), std::string::npos) << rock.output;
  EXPECT_NE(rock.output.find("no picture written"), std::string::npos) << rock.output;
  EXPECT_FALSE(std::filesystem::exists(path));
}

TEST(GrottoClient, a_screenshot_along_the_flythrough_is_not_blank) {
  const char* display = std::getenv("DISPLAY");
  if (display == nullptr || *display == '\0') GTEST_SKIP() << "DISPLAY is not set";
  const std::string path =
      (std::filesystem::temp_directory_path() / "grotto_client_test_flythrough.png").string();
  std::filesystem::remove(path);
  Outcome r = run(std::string(GROTTO_CLIENT_BIN) +
                  " --device none --seed 7 --width 320 --height 180 --tess-max 4 --frames 2" +
                  " --wait 120 --flythrough 3 --screenshot " + path);
  if (r.output.find("no OpenGL 4.1") != std::string::npos) GTEST_SKIP() << r.output;
  ASSERT_EQ(r.status, 0) << r.output;
  int width = 0, height = 0;
  std::vector<unsigned char> rgb = read_picture(path, width, height);
  ASSERT_EQ(rgb.size(), 320u * 180u * 3u);
  int differing = 0;
  for (size_t i = 3; i < rgb.size(); i += 3)
    differing += rgb[i] != rgb[0] || rgb[i + 1] != rgb[1];
  EXPECT_GT(differing, 320 * 180 / 4) << "the screenshot is nearly one colour";
  std::filesystem::remove(path);
}

}  // namespace

// The overlay in a real screenshot: pointed at a port where no server listens, grotto-client
// keeps running and its overlay says so in the error colour, in the top-left panel only; the
// screenshot still fails (exit 1, the reason on stderr). Without --overlay no picture is written.
TEST(GrottoClient, the_overlay_says_plainly_when_the_server_cannot_be_reached) {
  const char* display = std::getenv("DISPLAY");
  if (display == nullptr || *display == '\0') GTEST_SKIP() << "DISPLAY is not set";
  const auto dir = std::filesystem::temp_directory_path();
  // Port 9 (discard) on loopback: nothing listens there on these machines.
  const std::string base = std::string(GROTTO_CLIENT_BIN) +
                           " --server ws://127.0.0.1:9/ws --pose 0,0,0 --wait 1 --frames 2"
                           " --width 320 --height 180 --screenshot ";
  auto error_pixels = [&](const std::string& flags, int& outside_panel) {
    const std::string path = (dir / ("grotto_client_test_overlay" + flags + ".png")).string();
    std::filesystem::remove(path);
    Outcome r = run(base + path + " " + flags);
    // The screenshot failed (no rooms): exit 1 with the reason; with the overlay the picture of
    // it is written, without it none is.
    EXPECT_EQ(r.status, 1) << r.output;
    EXPECT_NE(r.output.find("--screenshot: no connection to the server within --wait 1 s"),
              std::string::npos)
        << r.output;
    EXPECT_EQ(std::filesystem::exists(path), flags == "--overlay") << r.output;
    int width = 0, height = 0;
    std::vector<unsigned char> rgb = read_picture(path, width, height);
    std::filesystem::remove(path);
    int count = 0;
    outside_panel = 0;
    for (int y = 0; y < height; ++y) {
      for (int x = 0; x < width; ++x) {
        const unsigned char* p = &rgb[(static_cast<size_t>(y) * width + x) * 3];
        // kOverlayError is (1.0, 0.35, 0.3): red well above green and blue.
        if (p[0] < 200 || p[1] > 120 || p[2] > 110) continue;
        ++count;
        outside_panel += y > height / 2;
      }
    }
    return count;
  };
  int outside = 0;
  EXPECT_GT(error_pixels("--overlay", outside), 100);
  EXPECT_EQ(outside, 0);
  EXPECT_EQ(error_pixels("", outside), 0);
}

// --screenshot --json: the view depth (depth_m) against the room's own mesh. From a room's
// interior point the camera faces the nearest wall, then the longest view across the room
// (both found by casting rays at the room's patch mesh); the picture facing the wall has a smaller
// median depth, and each median lies between what the mesh allows. A report that read the raw
// depth buffer (0-1), a far plane, or fog, would fall outside.
namespace {

// The distance along the ray from p in direction d (unit) to the nearest patch triangle of the
// mesh, or infinity.
double ray_distance(const grotto::mesh::RoomMesh& m, grotto::Vec3 p, grotto::Vec3 d) {
  using grotto::Vec3;
  double best = std::numeric_limits<double>::infinity();
  for (size_t t = 0; t + 2 < m.indices.size(); t += 3) {
    const Vec3 a = m.world_position(m.indices[t]), b = m.world_position(m.indices[t + 1]),
               c = m.world_position(m.indices[t + 2]);
    const Vec3 e1 = b - a, e2 = c - a, h = cross(d, e2);
    const double det = dot(e1, h);
    if (std::abs(det) < 1e-12) continue;
    const Vec3 s = p - a;
    const double u = dot(s, h) / det;
    if (u < 0 || u > 1) continue;
    const Vec3 q = cross(s, e1);
    const double v = dot(d, q) / det;
    if (v < 0 || u + v > 1) continue;
    const double along = dot(e2, q) / det;
    if (along > 0) best = std::min(best, along);
  }
  return best;
}

// The world of the depth test.
constexpr uint64_t kDepthSeed = 95;

struct Shot {
  int status = -1;
  std::string output;
  nlohmann::json report;
};

Shot shoot(const std::string& pose, const std::string& flags) {
  const auto dir = std::filesystem::temp_directory_path();
  const std::string png = (dir / "grotto_client_test_depth.png").string();
  const std::string json = (dir / "grotto_client_test_depth.json").string();
  std::filesystem::remove(png);
  std::filesystem::remove(json);
  Outcome r =
      run(std::string(GROTTO_CLIENT_BIN) + " --device none --seed " + std::to_string(kDepthSeed) +
          " --width 240 --height 160 --tess-max 4 --frames 2" + " --wait 120 --mode fly --pose " +
          pose + " --screenshot " + png + " --json " + json + flags);
  Shot shot{r.status, r.output, {}};
  std::ifstream f(json);
  if (f) shot.report = nlohmann::json::parse(f, nullptr, false);
  std::filesystem::remove(png);
  std::filesystem::remove(json);
  return shot;
}

}  // namespace

TEST(GrottoClient, screenshot_json_reports_the_view_depth_of_the_room_in_view) {
  const char* display = std::getenv("DISPLAY");
  if (display == nullptr || *display == '\0') GTEST_SKIP() << "DISPLAY is not set";
  namespace cave = grotto::cave;
  namespace mesh = grotto::mesh;
  using grotto::Vec3;
  // The world's largest room of sector (0,0,0), as the in-process server builds it.
  const cave::World world = cave::World::create(kDepthSeed, cave::LayoutParams{}).value();
  const mesh::MeshContext ctx = mesh::MeshContext::create(world, mesh::MeshParams{}).value();
  std::optional<cave::Room> room;
  for (const cave::Room& r : cave::generate_region(world, {0, 0, 0}, {0, 0, 0}).rooms)
    if (!r.id.is_gate() && (!room || r.sphere.radius > room->sphere.radius)) room = r;
  ASSERT_TRUE(room.has_value());
  const mesh::RoomMesh m = mesh::build_room_mesh(ctx, *room, mesh::Lod::kPatch).value();
  const Vec3 centre = cave::interior_point(*room);
  constexpr double kPi = 3.14159265358979323846;
  auto heading = [&](double yaw_deg) {
    const double a = yaw_deg * kPi / 180;  // yaw 0 looks along -z, positive yaw turns to +x
    return Vec3{std::sin(a), 0, -std::cos(a)};
  };
  // The nearest wall round the room's interior point, by horizontal rays every 10 degrees.
  double wall_yaw = 0, wall_d = std::numeric_limits<double>::infinity();
  for (int yaw = 0; yaw < 360; yaw += 10)
    if (const double d = ray_distance(m, centre, heading(yaw)); d < wall_d)
      wall_d = d, wall_yaw = yaw;
  ASSERT_TRUE(std::isfinite(wall_d)) << "no wall round " << room->id.to_string();
  // The camera 1.5 m from that wall: facing it, then facing back across the room.
  constexpr double kFromWall = 1.5;
  ASSERT_GT(wall_d, kFromWall + 1) << room->id.to_string() << " is too small for this test";
  const Vec3 eye = centre + heading(wall_yaw) * (wall_d - kFromWall);
  const double back_yaw = std::fmod(wall_yaw + 180, 360);
  const double wall_ahead = ray_distance(m, eye, heading(wall_yaw));
  const double across = ray_distance(m, eye, heading(back_yaw));  // infinity: out of a portal
  // What the mesh allows: no rock nearer than the nearest vertex less the relief (a pixel's
  // eye-space z is at most its distance from the eye; the corners of a 70 degree, 3:2 view are 45
  // degrees off its axis, so z is at least 0.7 of the distance).
  double nearest = 1e300, farthest = 0;
  for (size_t i = 0; i < m.vertex_count(); ++i) {
    const double d = length(m.world_position(i) - eye);
    nearest = std::min(nearest, d), farthest = std::max(farthest, d);
  }
  const double relief = grotto::relief::relief_bound(1.0f);
  auto pose = [&](double yaw) {
    char text[128];
    std::snprintf(text, sizeof text, "%.3f,%.3f,%.3f,%.0f,0", eye.x, eye.y, eye.z, yaw);
    return std::string(text);
  };
  const Shot near = shoot(pose(wall_yaw), "");
  if (near.output.find("no OpenGL 4.1") != std::string::npos) GTEST_SKIP() << near.output;
  ASSERT_EQ(near.status, 0) << pose(wall_yaw) << ": " << near.output;
  const Shot far = shoot(pose(back_yaw), "");
  ASSERT_EQ(far.status, 0) << pose(back_yaw) << ": " << far.output;
  // Without post passes the scene is drawn straight into the picture's framebuffer: the same depth.
  const Shot direct = shoot(pose(wall_yaw), " --no-bloom --no-motion-blur");
  ASSERT_EQ(direct.status, 0) << direct.output;
  for (const Shot* shot : {&near, &far, &direct}) {
    const nlohmann::json& j = shot->report;
    ASSERT_TRUE(j.is_object()) << "no JSON report: " << shot->output;
    for (const char* key : {"p10", "median", "p90"})
      ASSERT_TRUE(j["depth_m"][key].is_number()) << key << " in " << j.dump();
    EXPECT_LE(j["depth_m"]["p10"].get<double>(), j["depth_m"]["median"].get<double>());
    EXPECT_LE(j["depth_m"]["median"].get<double>(), j["depth_m"]["p90"].get<double>());
    EXPECT_GE(j["depth_m"]["p10"].get<double>(), 0.7 * (nearest - relief)) << j.dump();
    EXPECT_GT(j["covered"].get<double>(), 0.5) << j.dump();
    EXPECT_LE(j["covered"].get<double>(), 1.0);
    EXPECT_EQ(j["seed"].get<uint64_t>(), kDepthSeed);
    EXPECT_EQ(j["width"].get<int>(), 240);
    EXPECT_EQ(j["height"].get<int>(), 160);
    EXPECT_EQ(j["mode"].get<std::string>(), "fly");
    EXPECT_NEAR(j["pose"]["position"][0].get<double>(), eye.x, 1e-2);
    EXPECT_NEAR(j["pose"]["position"][1].get<double>(), eye.y, 1e-2);
    EXPECT_NEAR(j["pose"]["position"][2].get<double>(), eye.z, 1e-2);
    // The headlamp, on the player's head, first; then the world's lights within reach.
    ASSERT_GE(j["lights"].size(), 1u) << j.dump();
    EXPECT_EQ(j["lights"][0]["kind"].get<std::string>(), "headlamp");
    for (size_t i = 1; i < j["lights"].size(); ++i)
      EXPECT_NE(j["lights"][i]["kind"].get<std::string>(), "headlamp") << j.dump();
    const Vec3 lamp{j["lights"][0]["position"][0].get<double>(),
                    j["lights"][0]["position"][1].get<double>(),
                    j["lights"][0]["position"][2].get<double>()};
    EXPECT_LT(length(lamp - eye), 0.5);
  }
  const double near_median = near.report["depth_m"]["median"].get<double>();
  const double far_median = far.report["depth_m"]["median"].get<double>();
  std::printf(
      "depth: room %s radius %.1f m; mesh from the eye %.2f-%.2f m; wall %.2f m ahead at "
      "yaw %.0f: median %.2f m (p10 %.2f, p90 %.2f); across %.2f m at yaw %.0f: median "
      "%.2f m (p10 %.2f, p90 %.2f)\n",
      room->id.to_string().c_str(), room->sphere.radius, nearest, farthest, wall_ahead, wall_yaw,
      near_median, near.report["depth_m"]["p10"].get<double>(),
      near.report["depth_m"]["p90"].get<double>(), across, back_yaw, far_median,
      far.report["depth_m"]["p10"].get<double>(), far.report["depth_m"]["p90"].get<double>());
  // Facing the wall the view is shallower than across the room, and no deeper than the wall.
  EXPECT_LT(near_median, far_median);
  EXPECT_LE(near_median, wall_ahead + relief);
  // Across the room most of the view is farther than the wall was, and within the room's reach
  // unless the view leaves through a portal.
  EXPECT_GT(far_median, wall_ahead + relief);
  if (std::isfinite(across)) {
    EXPECT_LE(far_median, farthest + relief);
  }
  EXPECT_NEAR(direct.report["depth_m"]["median"].get<double>(), near_median, 0.01);
}
