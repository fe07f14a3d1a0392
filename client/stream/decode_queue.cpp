#include "client/stream/decode_queue.hpp"

namespace grotto::stream {

void DecodeQueue::push(std::chrono::steady_clock::time_point due, Job job) {
  std::lock_guard lock(mu_);
  // Unordered, every job is due at the same time and arrival alone orders them.
  const auto key = ordered_ ? due : std::chrono::steady_clock::time_point{};
  jobs_.emplace(std::make_pair(key, next_seq_++), std::move(job));
}

DecodeQueue::Job DecodeQueue::pop() {
  std::lock_guard lock(mu_);
  if (jobs_.empty()) return {};
  return std::move(jobs_.extract(jobs_.begin()).mapped());
}

size_t DecodeQueue::size() const {
  std::lock_guard lock(mu_);
  return jobs_.size();
}

}  // namespace grotto::stream
