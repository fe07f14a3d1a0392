// Overlay text and panels: flat coloured triangles placed in pixels from the top-left corner.
#version 410 core

layout(location = 0) in vec2 a_pixel;
layout(location = 1) in vec4 a_color;

uniform vec2 u_viewport;  // pixels

out vec4 v_color;

void main() {
  vec2 ndc = vec2(a_pixel.x / u_viewport.x * 2.0 - 1.0, 1.0 - a_pixel.y / u_viewport.y * 2.0);
  gl_Position = vec4(ndc, 0.0, 1.0);
  v_color = a_color;
}
