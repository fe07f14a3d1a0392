// Light in the dark as grotto-client shows it: which lights a frame takes
// (render::frame_lights, pure), a shot in a hall reporting the hall's world lights, and a hall lit
// by one flare with the headlamp off. The shots run the program against its in-process server
// (CPU reference) under the render tests' xvfb-run.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "client/render/renderer.hpp"
#include "common/cave/layout.hpp"
#include "common/cave/lights.hpp"

namespace grotto {
namespace {

render::Light point(const char* kind, Vec3 at, float range = 10) {
  render::Light l;
  l.kind = kind;
  l.position = at;
  l.colour = glm::vec3(1.0f);
  l.range = range;
  return l;
}

TEST(FrameLights, the_headlamp_first_then_flares_then_the_nearest_world_lights) {
  render::Camera camera;
  render::RenderOptions options;  // fog_end 64
  std::vector<render::Light> scene = {point("crystals", {0, 0, -20}),
                                      point("glow_worms", {0, 0, -5}), point("flare", {0, 0, -30}),
                                      point("mineral_seam", {0, 0, -80}, 10)};  // 80 > 10 + 64
  auto lights = render::frame_lights(camera, options, scene);
  ASSERT_EQ(lights.size(), 4u);
  EXPECT_EQ(lights[0].kind, "headlamp");
  EXPECT_EQ(lights[1].kind, "flare");
  EXPECT_EQ(lights[2].kind, "glow_worms");
  EXPECT_EQ(lights[3].kind, "crystals");
  options.headlamp = false;
  lights = render::frame_lights(camera, options, scene);
  ASSERT_EQ(lights.size(), 3u);
  EXPECT_EQ(lights[0].kind, "flare");
}

TEST(FrameLights, at_most_the_shaders_count_and_none_whose_room_is_beyond_the_fog) {
  render::Camera camera;
  render::RenderOptions options;
  options.headlamp = false;
  std::vector<render::Light> scene;
  for (int i = 0; i < 40; ++i)
    scene.push_back(point("crystals", {0, 0, -0.5 * i}, 20));
  auto lights = render::frame_lights(camera, options, scene);
  ASSERT_EQ(lights.size(), render::kMaxFrameLights);
  EXPECT_EQ(lights.back().position.z, -0.5 * (render::kMaxFrameLights - 1)) << "the nearest";
  // A light near the camera whose room lies wholly beyond the fog's end lights nothing seen.
  render::Light walled = point("crystals", {0, 0, -5}, 20);
  walled.bound_centre = {0, 0, -100};
  walled.bound_radius = 10;
  EXPECT_TRUE(render::frame_lights(camera, options, std::vector{walled}).empty());
  walled.bound_centre = {0, 0, -30};
  EXPECT_EQ(render::frame_lights(camera, options, std::vector{walled}).size(), 1u);
}

struct Shot {
  int status = -1;
  std::string output;
  nlohmann::json report;
};

Shot shoot(Vec3 eye, double yaw, const std::string& flags) {
  const auto dir = std::filesystem::temp_directory_path();
  const std::string png = (dir / "grotto_client_lights_test.png").string();
  const std::string json = (dir / "grotto_client_lights_test.json").string();
  std::filesystem::remove(png);
  std::filesystem::remove(json);
  char pose[128];
  std::snprintf(pose, sizeof pose, "%.3f,%.3f,%.3f,%.0f,0", eye.x, eye.y, eye.z, yaw);
  const std::string command = std::string(GROTTO_CLIENT_BIN) +
                              " --device none --seed 95 --width 240 --height 160 --tess-max 4"
                              " --frames 2 --wait 120 --mode fly --no-motion-blur --pose " +
                              pose + " --screenshot " + png + " --json " + json + " " + flags +
                              " 2>&1";
  Shot shot;
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) return shot;
  std::array<char, 4096> buffer{};
  size_t n = 0;
  while ((n = fread(buffer.data(), 1, buffer.size(), pipe)) > 0)
    shot.output.append(buffer.data(), n);
  const int status = pclose(pipe);
  shot.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  std::ifstream f(json);
  if (f) shot.report = nlohmann::json::parse(f, nullptr, false);
  std::filesystem::remove(png);
  std::filesystem::remove(json);
  return shot;
}

// Seed 95's hall in sectors 0,0,0..1,0,1 (bench/hall_views.sh's check): sector 1,0,1's hub.
cave::Room hall() {
  const auto world = cave::World::create(95, cave::LayoutParams{}).value();
  return cave::room(world, cave::RoomId::parse("1.0.1.r0").value()).value();
}

bool has_display() {
  const char* display = std::getenv("DISPLAY");
  return display != nullptr && *display != '\0';
}

TEST(LightsInTheClient, a_shot_in_a_hall_reports_the_halls_world_lights) {
  if (!has_display()) GTEST_SKIP() << "DISPLAY is not set";
  const cave::Room room = hall();
  ASSERT_TRUE(cave::floor_height(cave::LayoutParams{}, room.sphere)) << "1.0.1.r0 is no hall";
  const auto placed = cave::room_lights(95, cave::LayoutParams{}, room);
  ASSERT_GE(placed.size(), 3u);
  const Shot shot = shoot(room.sphere.centre, 270, "");
  if (shot.output.find("no OpenGL 4.1") != std::string::npos) GTEST_SKIP() << shot.output;
  ASSERT_EQ(shot.status, 0) << shot.output;
  const nlohmann::json& lights = shot.report["lights"];
  ASSERT_TRUE(lights.is_array()) << shot.output;
  EXPECT_EQ(lights[0]["kind"].get<std::string>(), "headlamp");
  // Every light the world placed in the hall lights the frame, as the world placed it.
  for (const cave::WorldLight& w : placed) {
    bool found = false;
    for (const auto& l : lights) {
      const Vec3 p{l["position"][0].get<double>(), l["position"][1].get<double>(),
                   l["position"][2].get<double>()};
      if (l["kind"].get<std::string>() == cave::light_kind_name(w.kind) &&
          distance(p, w.position) < 1e-6)
        found = true;
    }
    EXPECT_TRUE(found) << cave::light_kind_name(w.kind) << " at " << w.position.x << ","
                       << w.position.y << "," << w.position.z << " in " << lights.dump();
  }
  // Without them, only the headlamp.
  const Shot dark = shoot(room.sphere.centre, 270, "--no-world-lights");
  ASSERT_EQ(dark.status, 0) << dark.output;
  EXPECT_EQ(dark.report["lights"].size(), 1u) << dark.report.dump();
}

TEST(LightsInTheClient, with_the_headlamp_off_one_flare_lights_a_halls_far_wall) {
  if (!has_display()) GTEST_SKIP() << "DISPLAY is not set";
  const cave::Room room = hall();
  const double floor = cave::floor_height(cave::LayoutParams{}, room.sphere).value();
  // Standing near one side of the hall, looking across it (yaw 0: along -z).
  const Vec3 eye{room.sphere.centre.x, floor + 1.8,
                 room.sphere.centre.z + 0.65 * room.sphere.radius};
  const std::string unlit = "--no-headlamp --no-world-lights";
  const Shot dark = shoot(eye, 0, unlit);
  if (dark.output.find("no OpenGL 4.1") != std::string::npos) GTEST_SKIP() << dark.output;
  // Without it the hall is dark but for its faint ambient and mineral veins: little lit rock.
  ASSERT_EQ(dark.status, 0) << dark.output;
  EXPECT_LT(dark.report["lit_depth_m"]["covered"].get<double>(), 0.3) << dark.report.dump();

  const Shot lit = shoot(eye, 0, unlit + " --flares 1");
  ASSERT_EQ(lit.status, 0) << lit.output;
  ASSERT_EQ(lit.report["lights"].size(), 1u) << lit.report.dump();
  EXPECT_EQ(lit.report["lights"][0]["kind"].get<std::string>(), "flare");
  const nlohmann::json& reach = lit.report["lit_depth_m"];
  ASSERT_TRUE(reach["p90"].is_number()) << lit.report.dump();
  EXPECT_GE(reach["p90"].get<double>(), 20.0) << lit.report.dump();
  EXPECT_GT(reach["covered"].get<double>(), 0.3) << lit.report.dump();
  std::printf(
      "one flare, headlamp off: lit rock p10 %.1f median %.1f p90 %.1f m, %.0f %% of pixels\n",
      reach["p10"].get<double>(), reach["median"].get<double>(), reach["p90"].get<double>(),
      100 * reach["covered"].get<double>());
}

// A seam that lights a whole hall, seen from 3 m: its source is metres wide and its haze is
// screened over the picture in linear light, so the rock round it keeps its grain. Before, the
// falloff of a 1 m source and a gamma-encoded haze burnt 41 % of such a picture white (960x540).
TEST(LightsInTheClient, the_rock_beside_a_halls_seam_is_not_burnt_white) {
  if (!has_display()) GTEST_SKIP() << "DISPLAY is not set";
  const cave::Room room = hall();
  const auto placed = cave::room_lights(95, cave::LayoutParams{}, room);
  const cave::WorldLight* seam = nullptr;
  for (const cave::WorldLight& l : placed)
    if (l.kind == cave::LightKind::kMineralSeam) seam = &l;
  ASSERT_NE(seam, nullptr) << "seed 95's hall 1.0.1.r0 has a seam";
  // 3 m out from the rock it glows on, looking back at it (yaw 0 looks along -z).
  const Vec3 eye = seam->position + seam->facing * 3.0;
  const double yaw = std::atan2(-seam->facing.x, seam->facing.z) * 180 / 3.14159265358979;
  const Shot shot = shoot(eye, yaw, "");
  if (shot.output.find("no OpenGL 4.1") != std::string::npos) GTEST_SKIP() << shot.output;
  ASSERT_EQ(shot.status, 0) << shot.output;
  ASSERT_TRUE(shot.report["clipped"].is_number()) << shot.report.dump();
  const double clipped = shot.report["clipped"].get<double>();
  EXPECT_LT(clipped, 0.25) << shot.report.dump();
  EXPECT_GT(shot.report["lit_depth_m"]["covered"].get<double>(), 0.9) << shot.report.dump();
  std::printf("3 m from a hall's seam: %.1f %% of pixels clipped\n", 100 * clipped);
}

}  // namespace
}  // namespace grotto
