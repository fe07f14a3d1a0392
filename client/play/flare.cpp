#include "client/play/flare.hpp"

#include <algorithm>
#include <cmath>

namespace grotto::play {
namespace {

// Where along [p, q] (0..1) the segment meets the triangle, or a negative number when it does
// not: Möller-Trumbore as in collision.cpp's segment_crosses, which answers only whether (the
// flare needs the first of several hits).
double segment_hit(const Triangle& t, Vec3 p, Vec3 q) {
  const Vec3 dir = q - p, e1 = t.b - t.a, e2 = t.c - t.a;
  const Vec3 h = cross(dir, e2);
  const double det = dot(e1, h);
  if (std::abs(det) < 1e-18) return -1;
  const Vec3 s = p - t.a;
  const double u = dot(s, h) / det;
  if (u < 0 || u > 1) return -1;
  const Vec3 qv = cross(s, e1);
  const double v = dot(dir, qv) / det;
  if (v < 0 || u + v > 1) return -1;
  const double along = dot(e2, qv) / det;
  return along >= 0 && along <= 1 ? along : -1;
}

double segment_hit(const Disc& d, Vec3 p, Vec3 q) {
  const double sp = dot(p - d.centre, d.normal), sq = dot(q - d.centre, d.normal);
  if ((sp > 0 && sq > 0) || (sp < 0 && sq < 0) || sp == sq) return -1;
  const double along = sp / (sp - sq);
  const Vec3 x = p + (q - p) * along;
  return length_squared(x - d.centre) <= d.radius * d.radius ? along : -1;
}

}  // namespace

Flare throw_flare(Vec3 eye, Vec3 forward, const FlareParams& params) {
  const double l = length(forward);
  const Vec3 f = l > 1e-12 ? forward / l : Vec3{0, 0, -1};
  Flare flare;
  // From just in front of the eye, so the first step starts inside the player's room.
  flare.position = eye + f * 0.3;
  flare.velocity = f * params.speed + Vec3{0, params.lift, 0};
  return flare;
}

void add_flare(std::vector<Flare>& flares, const Flare& flare, const FlareParams& params) {
  flares.push_back(flare);
  const size_t keep = static_cast<size_t>(std::max(params.max_flares, 1));
  if (flares.size() > keep)
    flares.erase(flares.begin(),
                 flares.begin() + static_cast<std::ptrdiff_t>(flares.size() - keep));
}

void step_flare(Flare& flare, const CollisionWorld& world, const FlareParams& params) {
  const double dt = params.timestep;
  flare.age += dt;
  if (flare.resting) return;
  flare.velocity.y -= params.gravity * dt;
  const Vec3 p = flare.position;
  const Vec3 q = p + flare.velocity * dt;
  const double pad = params.radius + 0.05;
  const Vec3 lo{std::min(p.x, q.x) - pad, std::min(p.y, q.y) - pad, std::min(p.z, q.z) - pad};
  const Vec3 hi{std::max(p.x, q.x) + pad, std::max(p.y, q.y) + pad, std::max(p.z, q.z) + pad};
  thread_local Neighbourhood near;
  world.gather(lo, hi, near);
  double first = 2;
  Vec3 normal;
  for (const Triangle& t : near.triangles) {
    const double at = segment_hit(t, p, q);
    if (at >= 0 && at < first) {
      const Vec3 n = unit_normal(t);
      if (length_squared(n) == 0) continue;
      first = at;
      normal = n;
    }
  }
  for (const Disc& d : near.walls) {
    const double at = segment_hit(d, p, q);
    if (at >= 0 && at < first) first = at, normal = d.normal;
  }
  if (first > 1) {
    flare.position = q;
    return;
  }
  // Bounce off the surface it met: the normal faces the side the flare came from.
  if (dot(normal, flare.velocity) > 0) normal = -normal;
  flare.position = p + (q - p) * first + normal * params.radius;
  const double into = dot(flare.velocity, normal);  // negative
  const Vec3 along = flare.velocity - normal * into;
  flare.velocity = along * (1 - params.friction) - normal * (into * params.restitution);
  ++flare.bounces;
  if (normal.y > 0.6 && length(flare.velocity) < params.rest_speed) {
    flare.resting = true;
    flare.velocity = {};
  }
}

void advance_flares(std::vector<Flare>& flares, double dt, double& carry,
                    const CollisionWorld& world, const FlareParams& params) {
  carry += std::clamp(dt, 0.0, 0.25);
  while (carry >= params.timestep) {
    carry -= params.timestep;
    for (Flare& f : flares)
      step_flare(f, world, params);
  }
  std::erase_if(flares, [&](const Flare& f) { return f.age >= params.burn_s; });
}

double flare_brightness(const Flare& flare, const FlareParams& params) {
  if (flare.age >= params.burn_s) return 0;
  const double ignite = std::min(flare.age / 0.3, 1.0);
  const double fade = std::clamp((params.burn_s - flare.age) / 3.0, 0.0, 1.0);
  return ignite * fade;
}

}  // namespace grotto::play
