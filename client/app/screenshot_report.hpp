// grotto-client --screenshot --json: what a picture shows, written beside it. The view depth over
// the pixels that show rock (Renderer::read_view_depth: the scene pass's depth buffer linearized
// with the frame's near and far planes; the far plane, the clear colour, fog caps and rock wholly
// in fog do not count), the share of pixels that show rock, the lights that lit the frame, and
// the pose, seed and size it was taken with. Pure: no GL.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "client/render/renderer.hpp"
#include "common/core/vec3.hpp"

namespace grotto::app {

// Nearest-rank percentiles of the view depth over the pixels that show rock.
struct DepthSummary {
  size_t pixels = 0;   // all pixels of the picture
  size_t counted = 0;  // those that show rock
  double covered = 0;  // counted / pixels
  // Metres along the view axis; meaningless (and written as null) when counted is 0.
  double p10 = 0, median = 0, p90 = 0;
};

// depth_m: per pixel, metres, infinity (or NaN) where the pixel shows no rock.
DepthSummary summarize_depth(std::span<const float> depth_m);

struct ScreenshotReport {
  std::string picture;  // the PNG's path
  std::optional<uint64_t> seed;
  int width = 0, height = 0;
  Vec3 position;                      // the camera, world metres
  double yaw_deg = 0, pitch_deg = 0;  // --pose's convention
  std::string mode;                   // walk or fly
  DepthSummary depth;
  // The same over the pixels that show rock and are lit (any channel above 12 of 255, the
  // picture's own test for "lit"): how far the light reaches into the view.
  DepthSummary lit_depth;
  // The share of pixels with a channel at 250 of 255 or more (light burnt white).
  double clipped = 0;
  std::vector<render::Light> lights;
  size_t rooms_loaded = 0;
  int rooms_drawn = 0;
  bool relief = true;
  std::string gl_renderer;
  int formations = 0;                 // formation instances drawn in the last frame
  render::FrameStats::Passes passes;  // its GPU time per pass (passes_ms; null untimed)
};

std::string screenshot_json(const ScreenshotReport& report);

}  // namespace grotto::app
