// grotto-client --bench: frame times summarized (nearest-rank percentiles) and written as one
// line of text and as JSON. Pure: no GL.
#pragma once

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

namespace grotto::app {

struct BenchReport {
  // What was measured.
  size_t frames = 0;
  double seconds = 0;  // wall time of all frames
  double mean_ms = 0, median_ms = 0, p95_ms = 0, p99_ms = 0, max_ms = 0;
  double fps = 0;  // frames / seconds
  // Under what conditions.
  int width = 0, height = 0;
  float tess_max = 0;
  bool tessellation = true;
  std::string surface;
  bool relief = true, bloom = true, motion_blur = true;
  std::string gl_renderer;  // GL_RENDERER, e.g. "llvmpipe (LLVM 15.0.6, 256 bits)"
  std::string gl_version;   // GL_VERSION
  size_t rooms_loaded = 0;
  double patches_mean = 0;     // triangles submitted per frame
  double formations_mean = 0;  // formation instances drawn per frame
  // GPU milliseconds per pass, the median over the frames (GL timer queries: render::FrameStats::
  // Passes): rock, formations, caps, post. Empty where the queries gave nothing.
  std::vector<std::pair<std::string, double>> passes_ms;
  double path_length_m = 0;
  size_t path_rooms = 0;
};

// Fills the timing fields from per-frame milliseconds and the total wall time.
void summarize(std::vector<double> frame_ms, double seconds, BenchReport& report);
std::string bench_line(const BenchReport& report);
std::string bench_json(const BenchReport& report);

}  // namespace grotto::app
