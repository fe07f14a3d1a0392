// Tessellation levels: room.tesc's heuristics, shared with room.tese, which needs the step the
// relief is sampled at (relief_at_sampled). GLSL only: spliced into both stages by
// client/render/shaders.cpp (`#pragma grotto_include "lod.glsl"`).
uniform float u_max_tess;       // MaxTess; 1 disables tessellation
uniform float u_max_dist;       // MaxDist, metres
uniform int u_lod;              // 0 distance, 1 screen space, 2 silhouette
uniform float u_pixel_scale;    // pixels spanned by 1 m seen face-on at 1 m distance
uniform float u_target_pixels;  // screen space: pixels per tessellated segment

// The thesis's MaxTess * cos(D / MaxDist * pi/2), D metres from the camera.
float tess_distance_level(float dist) {
  float x = clamp(dist / u_max_dist, 0.0, 1.0);
  return max(1.0, u_max_tess * cos(x * 1.5707963267948966));
}

// An edge `len` metres long seen `dist` metres away (at least 1e-3): the pixels it spans over
// u_target_pixels pixels a segment.
float tess_screen_level(float len, float dist) {
  precise float pixels = len * u_pixel_scale / dist;
  return clamp(pixels / u_target_pixels, 1.0, u_max_tess);
}
