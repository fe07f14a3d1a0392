#pragma once
// f(0) ... f(count - 1) on `threads` threads (the caller's one of them), each index once, in no
// particular order: for work whose items are independent and whose results land by index.
#include <algorithm>
#include <atomic>
#include <cstddef>
#include <thread>
#include <vector>

namespace grotto {

template <class F>
void for_each_index(size_t count, int threads, F&& f) {
  const size_t extra = std::min(static_cast<size_t>(std::max(threads, 1)), count) - (count > 0);
  if (extra == 0) {
    for (size_t i = 0; i < count; ++i)
      f(i);
    return;
  }
  std::atomic<size_t> next{0};
  auto work = [&] {
    for (size_t i = next++; i < count; i = next++)
      f(i);
  };
  std::vector<std::thread> pool;
  pool.reserve(extra);
  for (size_t t = 0; t < extra; ++t)
    pool.emplace_back(work);
  work();
  for (std::thread& t : pool)
    t.join();
}

}  // namespace grotto
