// Kawase bloom (Ruby "Dangerous Curves" seed; Kawase 2003): the glow (the scene's colour times its
// alpha glow mask) is downsampled to a quarter of the screen in each direction, then blurred by
// ping-pong passes that each average four diagonal taps at a growing distance (offsets 0, 1, 2, 2,
// 3 texels), which approximates a wide Gaussian at a fraction of its taps.
#version 410 core

in vec2 v_uv;
out vec4 frag_color;

uniform sampler2D u_source;
uniform vec2 u_texel;    // one texel of u_source, in uv
uniform int u_downsample;  // 1: read the scene and keep its glow; 0: one Kawase pass
uniform float u_offset;  // texels: the Kawase pass's distance

vec3 glow(vec2 uv) {
  vec4 c = texture(u_source, uv);
  return c.rgb * c.a;
}

void main() {
  if (u_downsample == 1) {
    // 4 x 4 scene texels per target texel: 4 bilinear taps of 2 x 2 each.
    vec3 sum = glow(v_uv + u_texel * vec2(-1.0, -1.0)) + glow(v_uv + u_texel * vec2(1.0, -1.0)) +
               glow(v_uv + u_texel * vec2(-1.0, 1.0)) + glow(v_uv + u_texel * vec2(1.0, 1.0));
    frag_color = vec4(sum * 0.25, 1.0);
    return;
  }
  vec2 d = u_texel * (u_offset + 0.5);
  vec3 sum = texture(u_source, v_uv + vec2(-d.x, -d.y)).rgb +
             texture(u_source, v_uv + vec2(d.x, -d.y)).rgb +
             texture(u_source, v_uv + vec2(-d.x, d.y)).rgb + texture(u_source, v_uv + d).rgb;
  frag_color = vec4(sum * 0.25, 1.0);
}
