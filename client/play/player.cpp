#include "client/play/player.hpp"

#include <algorithm>
#include <array>
#include <cmath>

namespace grotto::play {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr int kResolveIterations = 8;  // the relief's small facets meet in crevices
constexpr int kMaxStepsPerAdvance = 30;

Vec3 horizontal(Vec3 v) {
  return {v.x, 0, v.z};
}

Vec3 unit_or_zero(Vec3 v) {
  const double l = length(v);
  return l > 0 ? v / l : Vec3{};
}

}  // namespace

const char* mode_name(Mode mode) {
  return mode == Mode::kWalk ? "walk" : "fly";
}

Player::Player(Vec3 eye, const PlayerParams& params) : params_(params), eye_(eye) {}

void Player::set_mode(Mode mode) {
  if (mode == mode_) return;
  mode_ = mode;
  grounded_ = false;
  velocity_ = {};
}

void Player::place(Vec3 eye) {
  eye_ = eye;
  velocity_ = {};
  grounded_ = false;
  accumulator_ = 0;
}

std::array<Vec3, 3> Player::spheres_at(Vec3 eye) const {
  const double span = params_.eye_height - params_.radius;  // eye to the feet sphere's centre
  return {eye - Vec3{0, span, 0}, eye - Vec3{0, span / 2, 0}, eye};
}

int Player::advance(double dt, const PlayerInput& input, const CollisionWorld& world) {
  accumulator_ += dt;
  int steps = static_cast<int>(std::floor(accumulator_ / params_.timestep));
  if (steps > kMaxStepsPerAdvance) {
    steps = kMaxStepsPerAdvance;  // a stall: drop the time rather than catch up all at once
    accumulator_ = 0;
  } else {
    accumulator_ -= steps * params_.timestep;
  }
  for (int i = 0; i < steps; ++i)
    step(input, world);
  return steps;
}

bool Player::resolve(Body& body, bool walking) const {
  const double r = params_.radius;
  const double rest = r + params_.skin / 2, reach = r + params_.skin;
  const double min_ground_y = std::cos(params_.max_slope_deg * kPi / 180);
  bool ground = false;
  // One contact: the sphere centre c against closest point q of a face with unit normal `face`.
  // Ground is a walkable face touched from above: an edge of a wall's facet is not ground, even
  // where the sphere sits above it.
  auto contact = [&](Vec3 c, Vec3 q, Vec3 face) {
    const Vec3 d = c - q;
    const double dist2 = length_squared(d);
    if (dist2 >= reach * reach) return false;
    const double dist = std::sqrt(dist2);
    const Vec3 n = dist > 1e-9 ? d / dist : face;
    const bool walkable = walking && n.y >= min_ground_y && face.y >= min_ground_y;
    ground = ground || walkable;
    if (walkable) {
      // Straight up onto the ground (the plane through q with normal n), no sideways creep; a
      // body falling or standing within reach settles at the resting gap too, so it never hovers.
      if (dist >= r && body.velocity.y > 0) return false;
      body.eye.y += (rest - dist) / n.y;
      body.velocity.y = std::max(body.velocity.y, 0.0);
      return dist < r;
    }
    if (dist >= r) return false;
    body.eye = body.eye + n * (rest - dist);
    const double into = dot(body.velocity, n);
    if (into < 0) body.velocity = body.velocity - n * into;
    return true;
  };
  const std::array<Vec3, 3> offsets = spheres_at(Vec3{});
  for (int iteration = 0; iteration < kResolveIterations; ++iteration) {
    bool pushed = false;
    for (const Vec3& offset : offsets) {
      for (const Triangle& t : near_.triangles) {
        const Vec3 c = body.eye + offset;
        pushed = contact(c, closest_point(t, c), unit_normal(t)) || pushed;
      }
      for (const Disc& wall : near_.walls) {
        const Vec3 c = body.eye + offset;
        // A centre exactly on the wall goes back into the loaded room.
        pushed = contact(c, closest_point(wall, c), -wall.normal) || pushed;
      }
    }
    if (!pushed) break;
  }
  // Where the pushes leave a sphere deeper than the skin (a body wedged between a stalactite and
  // the stalagmite beneath it, a crevice narrower than a sphere, pushes still fighting), say so:
  // the caller keeps the last place the body fitted.
  const double deepest = r - params_.skin;
  for (const Vec3& offset : offsets) {
    const Vec3 c = body.eye + offset;
    for (const Triangle& t : near_.triangles)
      if (length_squared(closest_point(t, c) - c) < deepest * deepest) body.wedged = true;
  }
  return ground;
}

bool Player::move(Body& body, Vec3 d, bool walking) const {
  const double max_substep = params_.radius / 2;
  const int n = std::max(1, static_cast<int>(std::ceil(length(d) / max_substep)));
  bool ground = false;
  for (int i = 0; i < n; ++i) {
    const Body settled = body;
    body.eye = body.eye + d / n;
    body.wedged = false;
    ground = resolve(body, walking);
    if (body.wedged) {
      // No room there: stay where the body last fitted, stopped.
      body = settled;
      body.velocity = {};
      return resolve(body, walking);
    }
  }
  return ground;
}

void Player::step(const PlayerInput& input, const CollisionWorld& world) {
  const double dt = params_.timestep;
  const double speed = params_.speed * (input.run ? params_.run_factor : 1);
  const bool walking = mode_ == Mode::kWalk && !noclip_;
  if (!walking) {
    const Vec3 vertical{0, (input.up ? 1.0 : 0.0) - (input.down ? 1.0 : 0.0), 0};
    velocity_ = unit_or_zero(unit_or_zero(input.move) + vertical) * speed;
    grounded_ = false;
    if (noclip_) {
      eye_ = eye_ + velocity_ * dt;
      return;
    }
  } else {
    const Vec3 wish = unit_or_zero(horizontal(input.move)) * speed;
    if (grounded_) {
      velocity_ = wish;
      if (input.up) velocity_.y = params_.jump_speed;
    } else {
      const Vec3 change = (wish - horizontal(velocity_)) * std::min(1.0, params_.air_control * dt);
      velocity_ = velocity_ + change - Vec3{0, params_.gravity * dt, 0};
    }
  }

  // Everything the body can reach this step, stepping up and snapping down included.
  const Vec3 d = velocity_ * dt;
  const double margin = params_.radius + params_.skin + params_.step_height + 0.1;
  Vec3 lo = eye_, hi = eye_;
  for (Vec3 c : spheres_at(eye_)) {
    for (Vec3 p : {c, c + d})
      for (int i = 0; i < 3; ++i)
        lo[i] = std::min(lo[i], p[i] - margin), hi[i] = std::max(hi[i], p[i] + margin);
  }
  world.gather(lo, hi, near_);

  const bool was_grounded = grounded_;
  const bool jumping = velocity_.y > 0;
  Body body{eye_, velocity_};
  bool ground = move(body, d, walking);

  if (walking && was_grounded && !jumping) {
    // Blocked while walking: try the same move from step_height higher, then down again; keep it
    // when it gets further and ends on walkable ground (ledges, rubble on the floor).
    const Vec3 wanted = horizontal(d);
    const double progress = length(horizontal(body.eye - eye_));
    if (length(wanted) > 0 && progress < 0.5 * length(wanted)) {
      Body stepped{eye_, velocity_};
      move(stepped, {0, params_.step_height, 0}, walking);
      move(stepped, wanted, walking);
      const bool landed = move(stepped, {0, -params_.step_height, 0}, walking);
      if (landed && length(horizontal(stepped.eye - eye_)) > progress + 1e-9) {
        body = stepped;
        ground = true;
      }
    }
    // Walking down a slope or off a small ledge: stay on the ground within step_height.
    if (!ground) {
      Body snapped = body;
      if (move(snapped, {0, -params_.step_height, 0}, walking)) {
        body = snapped;
        ground = true;
      }
    }
  }
  eye_ = body.eye;
  velocity_ = body.velocity;
  grounded_ = walking && ground && velocity_.y <= 0;
  if (grounded_) velocity_.y = 0;
}

}  // namespace grotto::play
