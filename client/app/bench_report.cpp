#include "client/app/bench_report.hpp"

#include <nlohmann/json.hpp>

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
                "%.0f patches per frame, path %.1f m through %zu rooms, %s)",
                r.frames, r.seconds, r.mean_ms, r.median_ms, r.p95_ms, r.p99_ms, r.max_ms, r.fps,
                r.width, r.height, r.tessellation ? r.surface.c_str() : "flat",
                static_cast<double>(r.tess_max), r.rooms_loaded, r.patches_mean, r.path_length_m,
                r.path_rooms, r.gl_renderer.c_str());
  return text;
}

std::string bench_json(const BenchReport& r) {
  nlohmann::json j = {
      {"frames", r.frames},
      {"seconds", r.seconds},
      {"mean_ms", r.mean_ms},
      {"median_ms", r.median_ms},
      {"p95_ms", r.p95_ms},
      {"p99_ms", r.p99_ms},
      {"max_ms", r.max_ms},
      {"fps", r.fps},
      {"width", r.width},
      {"height", r.height},
      {"tessellation", r.tessellation},
      {"surface", r.surface},
      {"tess_max", r.tess_max},
      {"relief", r.relief},
      {"bloom", r.bloom},
      {"motion_blur", r.motion_blur},
      {"gl_renderer", r.gl_renderer},
      {"gl_version", r.gl_version},
      {"rooms_loaded", r.rooms_loaded},
      {"patches_mean", r.patches_mean},
      {"formations", r.formations_mean},
      {"path_length_m", r.path_length_m},
      {"path_rooms", r.path_rooms},
  };
  j["passes_ms"] = nlohmann::json::object();
  for (const auto& [name, ms] : r.passes_ms)
    j["passes_ms"][name] = ms;
  return j.dump(2) + "\n";
}

}  // namespace grotto::app
