#include "server/send_queue.hpp"

#include <utility>

namespace grotto::server {

void SendQueue::push(Outgoing out) {
  bytes_ += out.size();
  auto at = queue_.end();
  if (ordered_ && out.room) {
    // Back to front: past the waiting rooms due later than this one, stopping at a control
    // message, a room due no later (ties keep arrival order) or the message being written.
    const auto first_movable = queue_.begin() + (writing_ && !queue_.empty() ? 1 : 0);
    while (at != first_movable) {
      const Outgoing& before = *std::prev(at);
      if (!before.room || before.due_ms <= out.due_ms) break;
      --at;
    }
  }
  queue_.insert(at, std::move(out));
}

void SendQueue::pop_front() {
  if (queue_.empty()) return;
  bytes_ -= queue_.front().size();
  queue_.pop_front();
  writing_ = false;
}

void SendQueue::drop_waiting() {
  const size_t keep = writing_ && !queue_.empty() ? 1 : 0;
  while (queue_.size() > keep) {
    bytes_ -= queue_.back().size();
    queue_.pop_back();
  }
}

void SendQueue::clear() {
  queue_.clear();
  bytes_ = 0;
  writing_ = false;
}

}  // namespace grotto::server
