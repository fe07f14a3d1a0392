#include "client/app/bench_report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>

namespace grotto::app {
namespace {

// Nearest rank: the smallest value with at least p of the values at or below it.
double percentile(const std::vector<double>& sorted, double p) {
  if (sorted.empty()) return 0;
  const size_t rank = static_cast<size_t>(std::ceil(p * static_cast<double>(sorted.size())));
  return sorted[std::clamp<size_t>(rank, 1, sorted.size()) - 1];
}

}  // namespace

void summarize(std::vector<double> frame_ms, double seconds, BenchReport& r) {
  std::sort(frame_ms.begin(), frame_ms.end());
  r.frames = frame_ms.size();
  r.seconds = seconds;
  r.mean_ms = frame_ms.empty() ? 0
                               : std::accumulate(frame_ms.begin(), frame_ms.end(), 0.0) /
                                     static_cast<double>(frame_ms.size());
  r.median_ms = percentile(frame_ms, 0.5);
  r.p95_ms = percentile(frame_ms, 0.95);
  r.p99_ms = percentile(frame_ms, 0.99);
  r.max_ms = frame_ms.empty() ? 0 : frame_ms.back();
  r.fps = seconds > 0 ? static_cast<double>(r.frames) / seconds : 0;
}

std::string bench_line(const BenchReport& r) {
  char text[512];
  std::snprintf(text, sizeof text,
                "grotto-client bench: %zu frames in %.2f s: mean %.2f ms, median %.2f ms, p95 "
                "%.2f ms, p99 %.2f ms, max %.2f ms, %.1f fps (%dx%d, %s, tess-max %g, %zu rooms, "
                "%.0f patches per frame, path %.1f m through %zu rooms)",
                r.frames, r.seconds, r.mean_ms, r.median_ms, r.p95_ms, r.p99_ms, r.max_ms, r.fps,
                r.width, r.height, r.tessellation ? r.surface.c_str() : "flat",
                static_cast<double>(r.tess_max), r.rooms_loaded, r.patches_mean, r.path_length_m,
                r.path_rooms);
  return text;
}

std::string bench_json(const BenchReport& r) {
  char text[1024];
  std::snprintf(text, sizeof text,
                "{\n  \"frames\": %zu,\n  \"seconds\": %.6f,\n  \"mean_ms\": %.6f,\n"
                "  \"median_ms\": %.6f,\n  \"p95_ms\": %.6f,\n  \"p99_ms\": %.6f,\n"
                "  \"max_ms\": %.6f,\n  \"fps\": %.6f,\n  \"width\": %d,\n  \"height\": %d,\n"
                "  \"tessellation\": %s,\n  \"surface\": \"%s\",\n  \"tess_max\": %g,\n"
                "  \"rooms_loaded\": %zu,\n  \"patches_mean\": %.3f,\n  \"path_length_m\": %.3f,\n"
                "  \"path_rooms\": %zu\n}\n",
                r.frames, r.seconds, r.mean_ms, r.median_ms, r.p95_ms, r.p99_ms, r.max_ms, r.fps,
                r.width, r.height, r.tessellation ? "true" : "false", r.surface.c_str(),
                static_cast<double>(r.tess_max), r.rooms_loaded, r.patches_mean, r.path_length_m,
                r.path_rooms);
  return text;
}

}  // namespace grotto::app
