#include "client/load/verifier.hpp"

#include <spdlog/spdlog.h>

#include "client/stream/verify.hpp"
#include "common/core/thread_name.hpp"

namespace grotto::load {

namespace {

void note(VerifyReport& report, const std::string& message) {
  spdlog::warn("event=verify_failed error=\"{}\"", message);
  if (report.first_failures.size() < PlayerVerifier::kMaxMessages) {
    report.first_failures.push_back(message);
  }
}

}  // namespace

void PlayerVerifier::check(
    const ReadyRoom& room,
    const std::function<std::shared_ptr<const ReadyRoom>(cave::RoomId)>& neighbour,
    VerifyReport& report) {
  ++report.rooms_checked;
  if (Status s = verify_room(room); !s) {
    ++report.room_failures;
    note(report, s.error().message);
  }
  if (Status s = graph_.add(room.room); !s) {
    ++report.graph_failures;
    note(report, s.error().message);
  }
  const uint64_t self = room.room.id.packed();
  for (const auto& portal : room.room.portals) {
    auto other = neighbour(portal.neighbour);
    if (!other) continue;
    const uint64_t them = portal.neighbour.packed();
    auto key = std::make_pair(std::min(self, them), std::max(self, them));
    if (!seams_.insert(key).second) continue;
    ++report.seams_checked;
    if (Status s = verify_seam(room, *other); !s) {
      ++report.seam_failures;
      note(report, s.error().message);
    }
  }
}

Verifier::Verifier(int players, RoomLookup lookup)
    : lookup_(std::move(lookup)), players_(static_cast<size_t>(players)) {
  report_.enabled = true;
  thread_ = std::thread([this] {
    name_this_thread("load-verify");
    run();
  });
}

Verifier::~Verifier() {
  finish();
}

void Verifier::push(int player, std::shared_ptr<const ReadyRoom> room) {
  {
    std::lock_guard lock(mutex_);
    queue_.emplace_back(player, std::move(room));
  }
  cv_.notify_one();
}

uint64_t Verifier::failures() const {
  std::lock_guard lock(mutex_);
  return report_.failures();
}

VerifyReport Verifier::finish() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  cv_.notify_one();
  if (thread_.joinable()) thread_.join();
  std::lock_guard lock(mutex_);
  return report_;
}

void Verifier::run() {
  std::unique_lock lock(mutex_);
  for (;;) {
    cv_.wait(lock, [this] { return stopping_ || !queue_.empty(); });
    if (queue_.empty()) return;  // stopping, and everything queued was checked
    auto [player, room] = std::move(queue_.front());
    queue_.pop_front();
    // The checks run unlocked so push() never waits for them; the report is merged after.
    lock.unlock();
    VerifyReport found;
    players_[static_cast<size_t>(player)].check(
        *room, [&, p = player](cave::RoomId id) { return lookup_(p, id); }, found);
    lock.lock();
    report_.rooms_checked += found.rooms_checked;
    report_.seams_checked += found.seams_checked;
    report_.room_failures += found.room_failures;
    report_.seam_failures += found.seam_failures;
    report_.graph_failures += found.graph_failures;
    for (auto& m : found.first_failures) {
      if (report_.first_failures.size() < PlayerVerifier::kMaxMessages) {
        report_.first_failures.push_back(std::move(m));
      }
    }
  }
}

}  // namespace grotto::load
