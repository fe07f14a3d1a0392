// The player: a body of three spheres stacked from the feet to the eye, moved at a fixed timestep
// against a CollisionWorld. Walk mode has gravity, ground detection, jumps, a walkable slope limit
// and steps; fly mode has no gravity and still collides; noclip (off by default, for debugging)
// flies through everything (no gravity, whatever the mode). Input is a plain struct, so tests
// drive it without a window. Pure double arithmetic in a fixed order: the same inputs give the
// same position bit for bit.
//
// Collision is a discrete slide: every fixed step is cut into substeps of at most half the
// sphere radius, and after each substep the spheres are pushed out of the triangles (and portal
// walls) they overlap, along the direction from the closest point (walkable ground pushes
// straight up, so nobody creeps down a slope). A centre that moves less than the radius between
// two resolutions cannot cross a surface it started at least radius - skin in front of, so the
// player never tunnels, also at run speed.
//
// Sizes (why): the display surface is the patch mesh plus the PN bulge plus up to 0.35 m of
// displacement (RenderOptions::displacement, on ceilings), so the eye keeps radius 0.5 m from the
// patch mesh: at least ~0.13 m of room for the bulge and the near plane (0.05 m, corners ~0.09 m)
// where displacement is largest. Eye 1.5 m above the feet, body 2.0 m tall: it passes the
// narrowest portal the layout makes (radius 1.2 m, min_portal_radius).
#pragma once

#include <array>

#include "client/play/collision.hpp"
#include "common/core/vec3.hpp"

namespace grotto::play {

enum class Mode { kWalk, kFly };
const char* mode_name(Mode mode);

struct PlayerInput {
  Vec3 move;          // wanted direction in world space; need not be unit; zero: stand still.
                      // Walk mode uses its horizontal part only.
  bool up = false;    // walk: jump (from the ground); fly: rise
  bool down = false;  // fly: descend
  bool run = false;
};

// Brace-init gives grotto-client's player.
struct PlayerParams {
  double radius = 0.5;      // of each body sphere (metres)
  double eye_height = 1.5;  // eye above the feet; the top sphere is centred on the eye
  double skin = 0.02;       // resting gap kept to surfaces (half of it) and contact reach
  double speed = 4;         // m/s walking or flying
  double run_factor = 2.5;  // Shift
  double jump_speed = 4.5;  // m/s upwards: jumps ~1 m
  double gravity = 9.81;
  double max_slope_deg = 50;  // steeper ground is a wall
  double step_height = 0.35;  // ledges up to this are stepped onto while walking
  double air_control = 4;     // 1/s: how fast horizontal velocity follows the input in the air
  double timestep = 1.0 / 120;
};

class Player {
 public:
  explicit Player(Vec3 eye, const PlayerParams& params = {});

  // Runs as many fixed steps as fit in dt plus the time left from earlier calls (at most a
  // quarter second's worth); returns the steps run.
  int advance(double dt, const PlayerInput& input, const CollisionWorld& world);
  // One fixed step of params().timestep.
  void step(const PlayerInput& input, const CollisionWorld& world);

  Vec3 eye() const { return eye_; }
  Vec3 velocity() const { return velocity_; }
  bool grounded() const { return grounded_; }
  Mode mode() const { return mode_; }
  bool noclip() const { return noclip_; }
  const PlayerParams& params() const { return params_; }
  void set_mode(Mode mode);
  void set_noclip(bool on) { noclip_ = on; }
  // Moves the player without collision (spawn, teleports); velocity zeroed.
  void place(Vec3 eye);
  // The centres of the body spheres, feet first.
  std::array<Vec3, 3> spheres() const { return spheres_at(eye_); }
  std::array<Vec3, 3> spheres_at(Vec3 eye) const;

 private:
  struct Body {
    Vec3 eye;
    Vec3 velocity;
    bool wedged = false;  // resolve() could not push every sphere clear
  };
  // Moves body by d in substeps, resolving after each; true when it touched walkable ground.
  bool move(Body& body, Vec3 d, bool walking) const;
  // Pushes the body out of what it overlaps; true when it touches walkable ground.
  bool resolve(Body& body, bool walking) const;

  PlayerParams params_;
  Vec3 eye_;
  Vec3 velocity_;
  bool grounded_ = false;
  Mode mode_ = Mode::kWalk;
  bool noclip_ = false;
  double accumulator_ = 0;
  Neighbourhood near_;  // gathered once per step
};

}  // namespace grotto::play
