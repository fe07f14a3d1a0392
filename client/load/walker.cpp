#include "client/load/walker.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>

namespace grotto::load {

const char* walker_state_name(WalkerState state) {
  switch (state) {
    case WalkerState::kWaiting:
      return "waiting";
    case WalkerState::kWalking:
      return "walking";
    case WalkerState::kStalled:
      return "stalled";
  }
  return "waiting";
}

Walker::Walker(WorldView view, const WalkerOptions& options, uint64_t seed)
    : view_(std::move(view)), options_(options), rng_(seed) {
  assert(view_.descriptor && view_.ready);
  assert(options_.speed > 0);
}

void Walker::place(cave::RoomId room, Vec3 position) {
  room_ = room;
  position_ = position;
  current_.reset();
  target_.reset();
  waypoint_.reset();
  came_from_.reset();
  turn_after_m_.reset();
  state_ = WalkerState::kWaiting;
}

std::optional<cave::RoomId> Walker::target() const {
  if (!target_) return std::nullopt;
  return target_->neighbour;
}

double Walker::current_speed() const {
  return burst_left_s_ > 0 ? options_.speed * options_.burst_factor : options_.speed;
}

Pose Walker::pose() const {
  Pose p;
  p.position = position_;
  p.forward = forward_;
  p.speed = current_speed();
  p.room = room_;
  return p;
}

void Walker::enter(const cave::Room& room, std::optional<cave::RoomId> from) {
  room_ = room.id;
  current_ = room;
  came_from_ = from;
  walked_in_room_m_ = 0;
  turn_after_m_.reset();
  state_ = WalkerState::kWalking;
  choose_portal(from);
}

void Walker::choose_portal(std::optional<cave::RoomId> from) {
  const auto& portals = current_->portals;
  std::vector<const cave::Portal*> onward;
  const cave::Portal* back = nullptr;
  for (const auto& p : portals) {
    if (from && p.neighbour == *from) {
      back = &p;
    } else {
      onward.push_back(&p);
    }
  }
  target_.reset();
  waypoint_.reset();
  if (onward.empty()) {
    // A dead end (or a room with no portals at all, where the walker stands still).
    if (back) {
      target_ = *back;
      waypoint_ = current_->sphere.centre;
      ++stats_.dead_ends;
    }
  } else {
    std::uniform_int_distribution<size_t> pick(0, onward.size() - 1);
    target_ = *onward[pick(rng_)];
    // Turning round part-way, rather than at the portal, reverses the view direction while the
    // prefetch plan still wants what lay ahead: the client has to cancel it.
    if (back && std::bernoulli_distribution(options_.turn_back_chance)(rng_)) {
      double way = distance(position_, target_->centre);
      turn_after_m_ = std::uniform_real_distribution<double>(0.3, 0.7)(rng_) * way;
    }
  }
  if (target_) {
    Vec3 to = (waypoint_ ? *waypoint_ : target_->centre) - position_;
    if (length_squared(to) > 0) forward_ = normalize(to);
  }
}

void Walker::update_burst(double dt) {
  if (burst_left_s_ > 0) {
    burst_left_s_ = std::max(0.0, burst_left_s_ - dt);
    return;
  }
  if (options_.burst_rate <= 0 || dt <= 0) return;
  double p = 1.0 - std::exp(-options_.burst_rate * dt);
  if (std::bernoulli_distribution(p)(rng_)) {
    burst_left_s_ =
        std::uniform_real_distribution<double>(options_.burst_min_s, options_.burst_max_s)(rng_);
    ++stats_.bursts;
  }
}

void Walker::advance(double dt) {
  assert(dt >= 0);
  const double start = time_;
  time_ += dt;
  if (!room_) return;

  if (state_ == WalkerState::kWaiting) {
    if (!view_.ready(*room_)) return;
    auto room = view_.descriptor(*room_);
    if (!room) return;
    if (!stats_.first_room_s) stats_.first_room_s = time_;
    bool neighbours = true;
    for (const auto& p : room->portals)
      neighbours &= view_.ready(p.neighbour);
    if (!neighbours && time_ - *stats_.first_room_s < options_.start_wait_s) return;
    enter(*room, std::nullopt);
    return;  // starts moving with the next step
  }

  if (state_ == WalkerState::kStalled) {
    cave::RoomId next = target_->neighbour;
    if (!view_.ready(next)) return;
    auto room = view_.descriptor(next);
    if (!room) return;
    stats_.stalls_s.push_back(time_ - stall_since_);
    ++stats_.rooms_entered;
    enter(*room, room_);
    return;
  }

  update_burst(dt);
  double left = dt;
  // Bounded: at any speed a step crosses at most a few rooms; the bound only guards a layout
  // with coincident portal centres.
  for (int i = 0; i < 64 && left > 0 && target_; ++i) {
    const double speed = current_speed();
    const Vec3 goal = waypoint_ ? *waypoint_ : target_->centre;
    const double to_goal = distance(position_, goal);
    if (to_goal > 0) forward_ = (goal - position_) / to_goal;
    double step = speed * left;

    if (turn_after_m_) {
      double until_turn = std::max(0.0, *turn_after_m_ - walked_in_room_m_);
      if (until_turn < to_goal && step >= until_turn) {
        position_ = position_ + forward_ * until_turn;
        walked_in_room_m_ += until_turn;
        stats_.distance_m += until_turn;
        left -= until_turn / speed;
        turn_after_m_.reset();
        for (const auto& p : current_->portals) {
          if (came_from_ && p.neighbour == *came_from_) target_ = p;
        }
        ++stats_.turn_backs;
        continue;
      }
    }

    if (step < to_goal) {
      position_ = position_ + forward_ * step;
      walked_in_room_m_ += step;
      stats_.distance_m += step;
      break;
    }
    position_ = goal;
    walked_in_room_m_ += to_goal;
    stats_.distance_m += to_goal;
    left -= to_goal / speed;
    if (waypoint_) {
      waypoint_.reset();
      continue;
    }

    cave::RoomId next = target_->neighbour;
    if (view_.ready(next)) {
      if (auto room = view_.descriptor(next)) {
        ++stats_.rooms_entered;
        enter(*room, room_);
        continue;
      }
    }
    state_ = WalkerState::kStalled;
    stall_since_ = start + (dt - left);
    break;
  }
}

}  // namespace grotto::load
