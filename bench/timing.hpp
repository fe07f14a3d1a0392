// Timing helpers the benchmark programs share: medians of repeated runs (the machines are shared
// and noisy; medians resist that) and the process's CPU time.
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <functional>
#include <utility>
#include <vector>

namespace grotto::bench {

// CPU seconds used so far by every thread of this process (PoCL's workers run in-process).
inline double process_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// The q-quantile of v (q in [0, 1]; the nearest rank at or above it; 0 for none).
inline double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  size_t i = static_cast<size_t>(std::ceil(q * static_cast<double>(v.size()))) - (q > 0 ? 1 : 0);
  return v[std::min(i, v.size() - 1)];
}

// The median of v (0 for none).
inline double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v[v.size() / 2];
}

// Median of `reps` timed runs of f, in milliseconds; *cpu_ms (if given) receives the median CPU
// time of the whole process over a run, which other load on the machine does not inflate.
inline double median_ms(int reps, const std::function<void()>& f, double* cpu_ms = nullptr) {
  using clock = std::chrono::steady_clock;
  std::vector<double> wall, cpu;
  for (int i = 0; i < reps; ++i) {
    auto start = clock::now();
    double cpu_start = process_cpu_seconds();
    f();
    wall.push_back(1000.0 * std::chrono::duration<double>(clock::now() - start).count());
    cpu.push_back(1000.0 * (process_cpu_seconds() - cpu_start));
  }
  if (cpu_ms) *cpu_ms = median(cpu);
  return median(wall);
}

// Two ways of doing one job timed in turn, f then g, `reps` times each, so the machine's load
// weighs on both alike: the median wall times of each, ms.
inline std::pair<double, double> median_ms_alternating(int reps, const std::function<void()>& f,
                                                       const std::function<void()>& g) {
  std::vector<double> a, b;
  for (int i = 0; i < reps; ++i) {
    a.push_back(median_ms(1, f));
    b.push_back(median_ms(1, g));
  }
  return {median(a), median(b)};
}

}  // namespace grotto::bench
