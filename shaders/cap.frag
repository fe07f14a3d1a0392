// Fog caps are drawn in the fog colour: what lies behind them is further than anyone can see.
#version 410 core

out vec4 frag_color;

uniform vec3 u_fog_color;

void main() {
  frag_color = vec4(u_fog_color, 0.0);  // alpha: no glow (the bloom pass)
}
