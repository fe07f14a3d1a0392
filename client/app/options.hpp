// grotto-client's command line: every flag, its default and its --help text, and the checks that
// flags make sense together. Errors name the flag and what was wrong.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "client/play/player.hpp"
#include "client/render/renderer.hpp"
#include "client/stream/net_sim.hpp"
#include "common/cave/room_id.hpp"
#include "common/core/vec3.hpp"

namespace grotto::app {

// --pose: a place and a view, or a room to start in.
struct Pose5 {
  Vec3 position;
  double yaw = 0, pitch = 0;         // degrees
  std::optional<cave::RoomId> room;  // room:<id>: inside this room, position unknown until then
};

struct Options {
  std::string server_url;  // empty: an in-process server
  std::optional<uint64_t> seed;
  uint32_t protocol_version = 0;  // offered in hello: 0 every version, else that one
  std::string device = "auto";
  int width = 1280;
  int height = 720;
  float tess_max = 8;
  float tess_pixels = render::RenderOptions{}.target_pixels;
  bool no_tess = false;
  bool wireframe = false;
  std::string surface = "pn";
  std::string screenshot;
  int frames = 30;
  std::string pose_text;
  std::optional<Pose5> pose;  // parsed from pose_text
  double wait_s = 60;
  double speed = 4;
  std::string mode_text = "walk";
  play::Mode mode = play::Mode::kWalk;
  std::optional<double> flythrough_s;  // time along the scripted path
  std::optional<double> bench_s;       // seconds of frames to measure
  bool hold = false;                   // --bench at the start pose, not along the path
  std::string json;                    // --bench or --screenshot report
  std::string token_file;
  std::string token;            // from token_file or $GROTTO_TOKEN; empty: none
  std::string net_text;         // --net: a simulated network (client/stream/net_sim.hpp)
  stream::NetProfile net;       // parsed from net_text; zero: the real network
  std::optional<bool> overlay;  // --overlay / --no-overlay; default: in the window only
  std::string lod_text = "screen";
  render::LodHeuristic lod = render::LodHeuristic::kScreenSpace;
  bool no_portal_culling = false;
  bool no_displacement = false;
  bool no_formations = false;  // the speleothems' instances (common/formations/formations.hpp)
  bool no_bloom = false;
  bool no_motion_blur = false;
  double exposure = 1.0;
  bool no_headlamp = false;      // Q toggles
  bool no_ao = false;            // K toggles: the relief's ambient occlusion
  bool no_fine_detail = false;   // J toggles: grain, pits and joints (relief_fine)
  bool no_world_lights = false;  // the world's glow-worms, seams and crystals (cave/lights.hpp)
  int flares = 0;                // --flares: thrown from the start pose before a screenshot
  std::string gl = "auto";       // --gl: auto, glfw or egl (see gl_context.hpp)
  std::string log_level = "warn";
};

// Speed along the scripted path (m/s) and its length in portals.
inline constexpr double kPathSpeed = 3.0;
inline constexpr int kPathHops = 6;

// Parses argv into `out`. Returns an exit code when the program should stop here (0 after
// --help, non-zero after an error, printed to stderr naming the flag), nullopt to go on.
std::optional<int> parse_options(int argc, char** argv, Options& out);

}  // namespace grotto::app
