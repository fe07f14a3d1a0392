// Flares: the player throws a flare from the eye; it falls under gravity,
// bounces off the collision surface (CollisionWorld: the rock as drawn, and the walls over
// portals to rooms not loaded) until it comes to rest, and burns as a bright warm point light for
// FlareParams::burn_s. A handful burn at once; throwing another puts out the oldest.
//
// Like the player: a fixed timestep and double arithmetic in a fixed order, so the same throws in
// the same world land in the same places (grotto-client --flares takes pictures of them). Each
// step moves the flare along a segment and stops it at the first triangle or wall the segment
// meets, so a fast flare never passes through a thin wall. No GL: play_tests drive it headless.
#pragma once

#include <vector>

#include "client/play/collision.hpp"
#include "common/core/vec3.hpp"

namespace grotto::play {

// Brace-init gives grotto-client's flares.
struct FlareParams {
  double speed = 12;          // m/s along the view when thrown
  double lift = 3;            // m/s upwards added to the throw (a lob)
  double gravity = 9.81;      // m/s^2
  double restitution = 0.35;  // share of the speed into a surface kept as it bounces off
  double friction = 0.35;     // share of the speed along a surface lost at each bounce
  double rest_speed = 0.6;    // m/s: slower than this on ground facing up, it lies still
  double radius = 0.04;       // metres: how far from a surface the flare's centre stays
  double burn_s = 30;         // seconds it burns
  int max_flares = 4;         // burning at once
  double timestep = 1.0 / 120;
};

struct Flare {
  Vec3 position;         // world metres
  Vec3 velocity;         // m/s
  double age = 0;        // seconds since thrown
  bool resting = false;  // lies still on the ground
  int bounces = 0;
};

// A flare leaving the eye along `forward` (need not be unit).
Flare throw_flare(Vec3 eye, Vec3 forward, const FlareParams& params = {});
// Adds a flare, putting out the oldest ones beyond params.max_flares.
void add_flare(std::vector<Flare>& flares, const Flare& flare, const FlareParams& params = {});
// Advances every flare by dt seconds in fixed steps of params.timestep (the remainder is carried
// in `carry`, seconds, between calls); removes the burnt-out ones.
void advance_flares(std::vector<Flare>& flares, double dt, double& carry,
                    const CollisionWorld& world, const FlareParams& params = {});
// One fixed step of one flare.
void step_flare(Flare& flare, const CollisionWorld& world, const FlareParams& params = {});
// How bright a flare burns at its age, 0..1: it flares up over a third of a second, holds, and
// dies down over the last 3 s; 0 once burnt out.
double flare_brightness(const Flare& flare, const FlareParams& params = {});

}  // namespace grotto::play
