#include "client/app/screenshot_report.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>

namespace grotto::app {
namespace {

// Nearest rank: the smallest value with at least p of the values at or below it.
double percentile(const std::vector<float>& sorted, double p) {
  const size_t rank = static_cast<size_t>(std::ceil(p * static_cast<double>(sorted.size())));
  return sorted[std::clamp<size_t>(rank, 1, sorted.size()) - 1];
}

nlohmann::json number_or_null(bool known, double value) {
  return known ? nlohmann::json(value) : nlohmann::json(nullptr);
}

}  // namespace

DepthSummary summarize_depth(std::span<const float> depth_m) {
  DepthSummary s;
  s.pixels = depth_m.size();
  std::vector<float> hit;
  hit.reserve(depth_m.size());
  for (float d : depth_m)
    if (std::isfinite(d)) hit.push_back(d);
  s.counted = hit.size();
  s.covered = s.pixels == 0 ? 0 : static_cast<double>(s.counted) / static_cast<double>(s.pixels);
  if (hit.empty()) return s;
  std::sort(hit.begin(), hit.end());
  s.p10 = percentile(hit, 0.1);
  s.median = percentile(hit, 0.5);
  s.p90 = percentile(hit, 0.9);
  return s;
}

std::string screenshot_json(const ScreenshotReport& r) {
  const bool hit = r.depth.counted > 0;
  nlohmann::json lights = nlohmann::json::array();
  for (const render::Light& l : r.lights)
    lights.push_back({{"kind", l.kind},
                      {"position", {l.position.x, l.position.y, l.position.z}},
                      {"range", l.range}});
  nlohmann::json j = {
      {"picture", r.picture},
      {"seed", r.seed ? nlohmann::json(*r.seed) : nlohmann::json(nullptr)},
      {"width", r.width},
      {"height", r.height},
      {"pose",
       {{"position", {r.position.x, r.position.y, r.position.z}},
        {"yaw", r.yaw_deg},
        {"pitch", r.pitch_deg}}},
      {"mode", r.mode},
      {"depth_m",
       {{"p10", number_or_null(hit, r.depth.p10)},
        {"median", number_or_null(hit, r.depth.median)},
        {"p90", number_or_null(hit, r.depth.p90)}}},
      {"covered", r.depth.covered},
      {"lit_depth_m",
       {{"p10", number_or_null(r.lit_depth.counted > 0, r.lit_depth.p10)},
        {"median", number_or_null(r.lit_depth.counted > 0, r.lit_depth.median)},
        {"p90", number_or_null(r.lit_depth.counted > 0, r.lit_depth.p90)},
        {"covered", r.lit_depth.covered}}},
      {"clipped", r.clipped},
      {"lights", lights},
      {"light_count", r.lights.size()},
      {"rooms_loaded", r.rooms_loaded},
      {"rooms_drawn", r.rooms_drawn},
      {"relief", r.relief},
      {"gl_renderer", r.gl_renderer},
      {"formations", r.formations},
  };
  if (r.passes.timed)
    j["passes_ms"] = {{"rock", r.passes.rock},
                      {"formations", r.passes.formations},
                      {"caps", r.passes.caps},
                      {"post", r.passes.post}};
  else
    j["passes_ms"] = nullptr;
  return j.dump(2) + "\n";
}

}  // namespace grotto::app
