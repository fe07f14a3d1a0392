// The composite: the scene, blurred along each pixel's motion, plus the bloom.
// Motion blur (Ruby "Dangerous Curves" seed): a pixel's world position comes back from its depth
// through the inverse of this frame's view-projection; last frame's view-projection tells where it
// was on screen; the scene is averaged along that velocity. Only the camera moves in the cave, so
// this is all the motion there is.
#version 410 core

in vec2 v_uv;
out vec4 frag_color;

uniform sampler2D u_scene;
uniform sampler2D u_depth;
uniform sampler2D u_bloom;
uniform float u_bloom_strength;  // 0: no bloom
uniform float u_motion;          // fraction of the frame's motion to smear; 0: no blur
uniform vec2 u_max_blur;         // the longest smear, in uv
uniform mat4 u_inverse_view_proj;
uniform mat4 u_previous_view_proj;  // last frame's, in this frame's anchor-relative space

const int kTaps = 8;

void main() {
  vec3 color = texture(u_scene, v_uv).rgb;
  if (u_motion > 0.0) {
    float depth = texture(u_depth, v_uv).r;
    vec4 clip = vec4(v_uv * 2.0 - 1.0, depth * 2.0 - 1.0, 1.0);
    vec4 world = u_inverse_view_proj * clip;
    world /= world.w;
    vec4 previous = u_previous_view_proj * world;
    vec2 velocity = vec2(0.0);
    if (previous.w > 1e-4) velocity = (clip.xy - previous.xy / previous.w) * 0.5 * u_motion;
    velocity = clamp(velocity, -u_max_blur, u_max_blur);
    if (dot(velocity, velocity) > 1e-8) {
      vec3 sum = color;
      for (int i = 1; i < kTaps; ++i) {
        float t = float(i) / float(kTaps - 1) - 0.5;
        sum += texture(u_scene, clamp(v_uv + velocity * t, 0.0, 1.0)).rgb;
      }
      color = sum / float(kTaps);
    }
  }
  color += u_bloom_strength * texture(u_bloom, v_uv).rgb;
  frag_color = vec4(color, 1.0);
}
