// The cave renderer: the rooms of a GpuRoomCache that the camera can see through portals (thesis
// §3.3.4) drawn as GL_PATCHES of 3 control points through shaders/room.{vert,tesc,tese,frag}
// (per-edge LOD by one of three heuristics, patch culling, PN triangles or Phong tessellation,
// the rock's relief of shaders/relief.glsl with stalactites and stalagmites, procedural rock, a
// headlamp, filmic tone mapping, fog into darkness), plus fog caps over portals whose room is not
// loaded; then, when on, Kawase bloom of glowing minerals and camera motion blur as post passes
// (shaders/post_*.frag). Needs a GL 4.1 core context current for its whole life.
#pragma once

#include <array>
#include <glm/glm.hpp>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "client/render/gl.hpp"
#include "client/render/room_cache.hpp"
#include "common/core/result.hpp"
#include "common/core/vec3.hpp"
#include "common/formations/formations.hpp"

namespace grotto::render {

// A first-person camera. yaw 0 looks along -z, positive yaw turns towards +x; pitch up is
// positive, clamped to ±89°; +y is up.
struct Camera {
  Vec3 position;
  double yaw = 0;                     // radians
  double pitch = 0;                   // radians
  double fov_y = 1.2217304763960306;  // radians (70°)
};
Vec3 camera_forward(const Camera& camera);

enum class Surface { kFlat = 0, kPnTriangles = 1, kPhong = 2 };

// How the TCS picks an edge's tessellation level. Every heuristic reads only the edge's two
// endpoints, symmetrically, so the two patches sharing an edge agree (no cracks).
enum class LodHeuristic {
  kDistance = 0,     // thesis §5.2.1: MaxTess * cos(D / MaxDist * pi/2), D to the edge's midpoint
  kScreenSpace = 1,  // the edge's projected length over RenderOptions::target_pixels
  kSilhouette = 2,   // Dyken et al.: half the distance level, the full level on silhouette edges
};
const char* lod_heuristic_name(LodHeuristic lod);

// Brace-init gives the defaults grotto-client uses.
struct RenderOptions {
  bool tessellation = true;  // false: flat triangles, no displacement
  float max_tess = 8;        // MaxTess of the distance heuristic (GL allows up to 64)
  float max_dist = 40;       // MaxDist: metres where the level falls to 1
  Surface surface = Surface::kPnTriangles;
  float phong_alpha = 0.75f;
  // Strength of the rock's relief (shaders/relief.glsl: rock, flowstone, speleothems): 1 as
  // designed, 0 off. Collision (client/play) uses the designed relief.
  float displacement = 1.0f;
  bool wireframe = false;
  bool fog_caps = true;  // discs over portals to rooms not loaded
  // Draw only rooms seen through portals from the camera's room (thesis §3.3.4); every room
  // (frustum-culled) when off or when the camera is in no loaded room.
  bool portal_culling = true;
  // The TCS discards patches provably outside the frustum or facing away from the camera.
  bool patch_culling = true;
  // Rooms whose rock (sphere, relief and hanging formations) is wholly outside the frustum are
  // not drawn; off only to check and measure that test.
  bool room_culling = true;
  // The speleothems (common/formations/formations.hpp), instanced meshes of their own; off: bare
  // rock.
  bool formations = true;
  // Time each pass on the GPU (GL timer queries: FrameStats::passes). Each frame then waits for
  // its queries: for benchmarks and reports, not for play.
  bool gpu_timing = false;
  LodHeuristic lod = LodHeuristic::kScreenSpace;  // near relief dense, far relief cheap
  float target_pixels = 9;                        // kScreenSpace: pixels per tessellated segment
  // Fog into darkness: a hall is up to 68 m across, and its far wall, lit by its own lights or a
  // flare, should show from its entrance.
  float fog_start = 24;  // metres
  float fog_end = 64;    // fully fogged here; must be below far_plane
  float near_plane = 0.05f;
  float far_plane = 96;
  float lamp_range = 14;  // metres at which the headlamp falls to about a tenth
  bool headlamp = true;   // off: only the world's lights and flares light the cave
  // Scattering per metre of the haze that the world's lights and flares light (shaders/
  // lights.glsl): halos round sources, shafts of light across a hall. 0: none.
  float haze = 0.03f;
  // The rock's fine detail (shaders/relief.glsl's relief_fine: grain, pits and joints from 5 cm
  // down to 1.6 cm, shading only, faded by each pixel's footprint); 0: none.
  float fine_detail = 1.0f;
  // Ambient occlusion from the relief (Relief::occlusion: its crevices and the feet of
  // formations, per tessellated vertex, no extra pass); off: none.
  bool ambient_occlusion = true;
  float exposure = 1.0f;  // before the filmic tone curve
  float glow = 1.0f;      // glowing mineral veins; 0: none
  bool bloom = true;      // Kawase bloom of the glow (post pass)
  float bloom_strength = 1.0f;
  int bloom_passes = 5;               // Kawase passes at a quarter of the resolution
  bool motion_blur = true;            // camera motion blur (post pass)
  float motion_blur_strength = 0.5f;  // fraction of a frame's motion smeared (a 180° shutter)
  float motion_blur_max = 0.03f;      // the longest smear, fraction of the screen
  // Display-space colour of the dark beyond the lamp.
  glm::vec3 fog_color{0.010f, 0.011f, 0.013f};
  glm::vec3 clear_color{0.010f, 0.011f, 0.013f};  // tests clear to a colour the cave never has
};

struct FrameStats {
  int rooms_reached = 0;  // through portals (every loaded room without portal culling)
  int rooms_drawn = 0;
  int rooms_culled = 0;         // reached but outside the view frustum
  int portals_tested = 0;       // portal rectangles tested against a clip rectangle
  bool camera_located = false;  // the camera is in a loaded room (portal culling applies)
  size_t patches = 0;           // triangles submitted as patches
  int caps = 0;                 // fog caps drawn
  bool motion_cut = false;      // no motion blur: first frame, or the camera jumped
  int formations = 0;           // formation instances drawn
  size_t formation_triangles = 0;
  // GPU milliseconds of each pass (RenderOptions::gpu_timing; all 0 without it): the rooms'
  // tessellated rock (with their lighting), the formations, the fog caps, the post passes.
  struct Passes {
    bool timed = false;
    double rock = 0, formations = 0, caps = 0, post = 0;
  } passes;
};

// A light source that lights a frame: what it is ("headlamp", a world light's
// cave::light_kind_name, "flare") and where it is, world metres. World lights and flares are point
// lights with shaders/lights.glsl's falloff (cave/lights.hpp's convention) and a patch of glowing
// rock round them; the headlamp is room.frag's own (its colour and range unused here).
struct Light {
  std::string kind;
  Vec3 position;
  glm::vec3 colour{0.0f};   // linear RGB x intensity at 1 m
  float range = 0;          // metres where its light reaches zero
  float size = 0;           // metres: the glowing patch of rock round the source
  float source_radius = 1;  // metres: the r of its falloff 1 / (r^2 + d^2) (cave/lights.hpp)
  int glow = 0;             // the patch's pattern: shaders/lights.glsl's GLOW_* (3: a flare)
  // It lights only rock within this sphere (its room's, grown for the relief: the rock between
  // rooms casts no shadow in the shader); radius 0: everywhere in range.
  Vec3 bound_centre{};
  float bound_radius = 0;
  // The room it lights (the bound's): the rooms through that room's portals get its light a few
  // metres past the bound (shaders/lights.glsl's kLightSpill), so a passage seen from a hall
  // shows its first metres lit and darkening into the passage instead of a flat black disc.
  // None: no spill.
  std::optional<cave::RoomId> room{};
};
// Lights of the scene at most that one frame shades with (shaders/lights.glsl's
// GROTTO_MAX_LIGHTS), besides the headlamp.
inline constexpr size_t kMaxFrameLights = 16;
// The lights of a frame drawn from `camera` with `options`, out of the scene's `scene` (world
// lights of the loaded rooms, flares): the headlamp first when options.headlamp (a little above
// and right of the eye), then the scene's lights whose light can reach rock the camera sees
// before the fog's end (nearer than range + fog_end), flares before world lights, nearest first,
// kMaxFrameLights at most. One source of truth: the renderer lights the frame with these, and
// grotto-client --screenshot --json reports them.
std::vector<Light> frame_lights(const Camera& camera, const RenderOptions& options,
                                std::span<const Light> scene = {});

// A power-of-two grid point near the camera: room offsets from it are exact in float32.
Vec3 render_anchor(Vec3 camera_position);

class Renderer {
 public:
  // Builds the programs (embedded shaders); errors carry the driver's log.
  static Result<Renderer> create();
  // Clears the bound framebuffer (viewport width x height) and draws the cache, lit by
  // frame_lights(camera, options, scene_lights).
  FrameStats draw(const GpuRoomCache& cache, const Camera& camera, int width, int height,
                  const RenderOptions& options, std::span<const Light> scene_lights = {});
  // The view depth of the last frame's scene pass, read back from its depth buffer and
  // linearized with that frame's near and far planes: per pixel, rows top first (read_rgb's
  // order), the distance in metres along the view axis (eye-space z) to the rock the pixel shows.
  // Infinity where the pixel shows no rock: nothing drawn (the far plane, the clear colour) or
  // rock wholly in fog (as far from the eye as RenderOptions::fog_end or more). Fog caps write
  // no depth, so they count as nothing drawn. Call with the last frame's GL context current and
  // its framebuffers alive; empty before the first frame.
  std::vector<float> read_view_depth() const;

 private:
  // The post passes' targets, made for one size and remade when it changes.
  struct PostTargets {
    int width = 0, height = 0;
    FramebufferName scene;  // colour (rgb + glow alpha) and depth textures
    Texture scene_color, scene_depth;
    FramebufferName bloom[2];  // quarter size, ping-pong
    Texture bloom_color[2];
  };
  Status ensure_post_targets(int width, int height);
  // The lights of the frame (the headlamp aside) that reach one room, by their index in the
  // frame's arrays. Only those whose light can reach the room's rock and formations shade it
  // (room.frag loops over them per pixel: on llvmpipe every one costs, and most rooms are lit by
  // none or one room's few); the haze (per vertex) also takes those whose bound holds the camera,
  // since the view ray to this room's surfaces crosses it.
  struct RoomLights {
    std::array<GLint, kMaxFrameLights> shading{}, hazing{};
    std::array<GLfloat, kMaxFrameLights> next_door{};  // by k, as shading: room.frag's
                                                       // u_light_next_door
    int shade_count = 0, haze_count = 0;
  };
  struct DrawnRoom {
    const GpuRoom* room;
    RoomLights lights;
  };
  // reach: how far past the room's sphere centre its surfaces lie (radius and margins).
  static RoomLights lights_reaching(std::span<const Light* const> points, const cave::Room& room,
                                    Vec3 camera, double reach);
  // The formations of `rooms` inside the frustum (unit planes, anchor-relative), each at the
  // level of detail its size on screen asks for, none under a pixel; lit by its room's lights.
  void draw_formations(const std::vector<DrawnRoom>& rooms, Vec3 anchor, glm::vec3 eye,
                       const std::array<glm::vec4, 6>& planes, float pixel_scale,
                       FrameStats& stats);
  void post_process(GLint target, int width, int height, const glm::mat4& view_proj,
                    const glm::mat4& previous_view_proj, const RenderOptions& options);

  // The uniforms room.frag reads, located in one program (the rooms' or the formations').
  struct RoomUniforms {
    GLint room_offset, relief_margin, camera, max_tess, max_dist, view_proj, block, surface,
        phong_alpha, displacement, fog_color, fog_start, fog_end, lamp_range, lod, pixel_scale,
        target_pixels, patch_culling, frustum, fine_detail, ao, lamp, forward, exposure, glow,
        light_count, light_position, light_color, light_glow, light_bound, light_index, headlamp,
        haze, patch_edge, haze_count, haze_index, light_next_door;
  };
  static RoomUniforms locate(const Program& p);
  static void set_room_lights(const RoomUniforms& u, const RoomLights& lights);
  // One formation mesh: rings x sides, drawn instanced.
  struct FormationLod {
    VertexArray vertex_array;
    Buffer grid, indices;
    GLsizei index_count = 0;
    int sides = 0, rings = 0;
  };
  static constexpr int kFormationLods = formations::kLods;

  Program room_;
  Program formation_;
  Program cap_;
  Program bloom_;
  Program composite_;
  VertexArray cap_vertex_array_;
  Buffer cap_vertices_;
  VertexArray post_vertex_array_;  // empty: post.vert makes its triangle from gl_VertexID
  PostTargets post_;
  RoomUniforms u_{};
  RoomUniforms uf_{};  // formation_'s
  FormationLod formation_lods_[kFormationLods];
  Buffer formation_instances_;
  Query queries_[4];  // FrameStats::Passes, in its order
  struct BloomUniforms {
    GLint source, texel, downsample, offset;
  } ub_{};
  struct CompositeUniforms {
    GLint scene, depth, bloom, bloom_strength, motion, max_blur, inverse_view_proj,
        previous_view_proj;
  } uc_{};
  GLint cap_view_proj_ = -1;
  GLint cap_fog_color_ = -1;
  // Where and how the last frame's scene pass was drawn, for read_view_depth.
  struct SceneDepth {
    GLuint framebuffer = 0;
    int width = 0, height = 0;
    float near_plane = 0, far_plane = 0, fog_end = 0;
    float tan_half_fov_y = 0, aspect = 1;
  } last_scene_{};
  // Last frame's camera, for motion blur.
  bool has_previous_ = false;
  Camera previous_camera_;
  glm::mat4 previous_view_proj_{1.0f};  // anchor-relative to previous_anchor_
  Vec3 previous_anchor_;
};

}  // namespace grotto::render
