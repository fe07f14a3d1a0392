#include "client/render/renderer.hpp"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <cstdio>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <limits>
#include <map>
#include <tuple>
#include <vector>

#include "client/render/shaders.hpp"
#include "client/stream/verify.hpp"
#include "common/cave/lights.hpp"
#include "common/core/random.hpp"
#include "common/mesh/rim.hpp"
#include "common/relief/relief.hpp"

namespace grotto::render {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kMaxPitch = 89.0 * kPi / 180.0;
// The anchor grid: a power of two, so anchor coordinates are exact and room offsets from it stay
// below 65,536 m for any room near the camera: the float32-exact frame of the wire's 1/256 m
// grid (grid::kWireStepLog2), on which every server's room origins lie.
constexpr double kAnchorStep = 1024.0;
// A camera that moved further than this between two frames jumped (a cut): no motion blur.
constexpr double kCutDistance = 2.0;  // metres
constexpr double kCutAngle = 0.6;     // radians of yaw or pitch
constexpr int kCapSegments = 24;
constexpr double kCapScale = 1.03;   // caps overlap the rim loop's wall (beyond its reach)
constexpr double kCapOffset = 0.01;  // metres beyond the portal plane

glm::vec3 to_vec3(Vec3 v) {
  return {static_cast<float>(v.x), static_cast<float>(v.y), static_cast<float>(v.z)};
}

Vec3 normalized(Vec3 v) {
  double n = std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z);
  return n > 0 ? Vec3{v.x / n, v.y / n, v.z / n} : Vec3{0, 0, 0};
}

// The radius of a disc that covers `portal`'s opening and overlaps its wall: rims move with the
// surface noise, up to mesh::rim_reach from the centre (the default world's mesh parameters).
double cover_radius(const cave::Portal& portal) {
  static const mesh::MeshParams params;
  return mesh::rim_reach(params, portal.radius) * kCapScale;
}

// The fan of a disc over `portal` (anchor-relative), appended as triangles.
void append_cap(const cave::Portal& portal, Vec3 anchor, std::vector<float>& out) {
  Vec3 n = normalized(portal.normal);
  Vec3 helper = std::abs(n.y) < 0.9 ? Vec3{0, 1, 0} : Vec3{1, 0, 0};
  Vec3 t = normalized(cross(n, helper));
  Vec3 b = cross(n, t);
  Vec3 centre = portal.centre + n * kCapOffset - anchor;
  double r = cover_radius(portal);
  auto point = [&](int k) {
    double a = 2 * kPi * k / kCapSegments;
    return centre + t * (r * std::cos(a)) + b * (r * std::sin(a));
  };
  for (int k = 0; k < kCapSegments; ++k) {
    for (Vec3 p : {centre, point(k), point(k + 1)}) {
      out.push_back(static_cast<float>(p.x));
      out.push_back(static_cast<float>(p.y));
      out.push_back(static_cast<float>(p.z));
    }
  }
}

// The six planes of the view frustum (Gribb & Hartmann 2001), unnormalized, from clip space.
std::array<glm::vec4, 6> frustum_planes(const glm::mat4& m) {
  const glm::vec4 r0{m[0][0], m[1][0], m[2][0], m[3][0]};
  const glm::vec4 r1{m[0][1], m[1][1], m[2][1], m[3][1]};
  const glm::vec4 r2{m[0][2], m[1][2], m[2][2], m[3][2]};
  const glm::vec4 r3{m[0][3], m[1][3], m[2][3], m[3][3]};
  return {r3 + r0, r3 - r0, r3 + r1, r3 - r1, r3 + r2, r3 - r2};
}

// Whether a room's rock (within its sphere grown by `margin` metres: how far drawn rock can lie
// from the surface it was sent as, the relief along the normal and PN bulges) is wholly outside
// one of the frustum's planes. (The formations are culled one by one: draw_formations.)
bool sphere_outside(const std::array<glm::vec4, 6>& planes, glm::vec3 c, float radius,
                    float margin) {
  for (const glm::vec4& p : planes) {
    const glm::vec3 n{p};
    const float reach = (radius + margin) * glm::length(n);
    if (glm::dot(n, c) + p.w < -reach) return true;
  }
  return false;
}

// An axis-aligned rectangle in normalized device coordinates.
struct ScreenRect {
  float x0 = -1, y0 = -1, x1 = 1, y1 = 1;  // brace-init: the whole screen
  bool empty() const { return !(x0 < x1 && y0 < y1); }
  bool contains(const ScreenRect& r) const {
    return x0 <= r.x0 && y0 <= r.y0 && r.x1 <= x1 && r.y1 <= y1;
  }
};

ScreenRect intersect(const ScreenRect& a, const ScreenRect& b) {
  return {std::max(a.x0, b.x0), std::max(a.y0, b.y0), std::min(a.x1, b.x1), std::min(a.y1, b.y1)};
}

ScreenRect unite(const ScreenRect& a, const ScreenRect& b) {
  return {std::min(a.x0, b.x0), std::min(a.y0, b.y0), std::max(a.x1, b.x1), std::max(a.y1, b.y1)};
}

// What the camera can see of a portal's opening.
struct PortalView {
  enum Kind { kHidden, kRect, kNearPlane } kind = kHidden;
  ScreenRect rect;  // kRect: contains the opening's projection
};

// The opening of `portal` (what shows the neighbour) lies within a slab around the portal's disc:
// the rim loop stays inside the disc grown like the caps, and PN bulges and displacement of the
// patches next to it move the surface by less than `margin` (the same bound as room culling).
// Bounded by a circumscribed octagon of that disc grown by `margin`, at ±margin along the normal:
// 16 points whose convex hull holds the opening. Hidden when every point is outside one clip plane;
// kNearPlane when a point is not in front of the near plane (the projection of the hull is then no
// rectangle, so the portal passes with its parent's rectangle).
PortalView view_portal(const cave::Portal& portal, Vec3 anchor, const glm::mat4& view_proj,
                       float near_plane, float margin) {
  constexpr int kSides = 8;
  const Vec3 n = normalized(portal.normal);
  const Vec3 helper = std::abs(n.y) < 0.9 ? Vec3{0, 1, 0} : Vec3{1, 0, 0};
  const Vec3 t = normalized(cross(n, helper));
  const Vec3 b = cross(n, t);
  const double r = (cover_radius(portal) + margin) / std::cos(kPi / kSides);
  std::array<glm::vec4, 2 * kSides> clip;
  for (int k = 0; k < kSides; ++k) {
    const double a = 2 * kPi * (k + 0.5) / kSides;
    const Vec3 rim = portal.centre - anchor + t * (r * std::cos(a)) + b * (r * std::sin(a));
    for (int side = 0; side < 2; ++side) {
      const Vec3 p = rim + n * (side == 0 ? -margin : static_cast<double>(margin));
      clip[2 * k + side] = view_proj * glm::vec4(to_vec3(p), 1.0f);
    }
  }
  // Outside one of the six clip planes (-w <= x, y, z <= w) with every point: hidden.
  for (int axis = 0; axis < 3; ++axis) {
    for (float sign : {-1.0f, 1.0f}) {
      if (std::all_of(clip.begin(), clip.end(),
                      [&](const glm::vec4& c) { return sign * c[axis] > c.w; }))
        return {};
    }
  }
  PortalView out;
  if (std::any_of(clip.begin(), clip.end(),
                  [&](const glm::vec4& c) { return c.w <= near_plane; })) {
    out.kind = PortalView::kNearPlane;
    return out;
  }
  out.kind = PortalView::kRect;
  out.rect = {1, 1, -1, -1};
  for (const glm::vec4& c : clip) {
    out.rect.x0 = std::min(out.rect.x0, c.x / c.w);
    out.rect.x1 = std::max(out.rect.x1, c.x / c.w);
    out.rect.y0 = std::min(out.rect.y0, c.y / c.w);
    out.rect.y1 = std::max(out.rect.y1, c.y / c.w);
  }
  return out;
}

// The rooms the camera is in: inside the room's sphere and not beyond any of its portal planes,
// both with `tolerance`. A camera standing in a portal is in both rooms.
std::vector<cave::RoomId> rooms_holding(const GpuRoomCache& cache, Vec3 camera, double tolerance) {
  std::vector<cave::RoomId> out;
  for (const auto& [id, room] : cache.rooms()) {
    const cave::Sphere& s = room.room.sphere;
    const double reach = s.radius + stream::vertex_sphere_margin(s.radius) + tolerance;
    const Vec3 d = camera - s.centre;
    if (d.x * d.x + d.y * d.y + d.z * d.z > reach * reach) continue;
    const bool inside =
        std::all_of(room.room.portals.begin(), room.room.portals.end(), [&](const cave::Portal& p) {
          const Vec3 q = camera - p.centre;
          return q.x * p.normal.x + q.y * p.normal.y + q.z * p.normal.z <= tolerance;
        });
    if (inside) out.push_back(id);
  }
  return out;
}

// Portal rendering (thesis §3.3.4): from the rooms holding the camera, through every portal whose
// opening overlaps the clip rectangle the room was reached with, narrowing the rectangle to the
// portal's. A room reached along several paths keeps the union of their rectangles and is expanded
// again when it grows. Empty when the camera is in no loaded room.
std::map<cave::RoomId, ScreenRect> reach_through_portals(const GpuRoomCache& cache, Vec3 camera,
                                                         Vec3 anchor, const glm::mat4& view_proj,
                                                         float near_plane, float margin,
                                                         FrameStats& stats) {
  // A camera this close to a portal plane stands in the portal: both rooms are its rooms.
  constexpr double kLocateTolerance = 0.25;
  std::map<cave::RoomId, ScreenRect> reached;
  std::vector<cave::RoomId> work;
  for (cave::RoomId id : rooms_holding(cache, camera, kLocateTolerance)) {
    reached[id] = ScreenRect{};
    work.push_back(id);
  }
  // Rectangles only grow, so this ends; the bound is a guard against float creep.
  size_t budget = 16 * cache.size() + 64;
  while (!work.empty()) {
    if (budget-- == 0) return {};  // give up: the caller draws everything
    const cave::RoomId id = work.back();
    work.pop_back();
    const ScreenRect rect = reached.at(id);
    for (const cave::Portal& portal : cache.rooms().at(id).room.portals) {
      if (!cache.contains(portal.neighbour)) continue;  // a fog cap, not a room
      ++stats.portals_tested;
      const PortalView seen = view_portal(portal, anchor, view_proj, near_plane, margin);
      if (seen.kind == PortalView::kHidden) continue;
      const ScreenRect clip = seen.kind == PortalView::kRect ? intersect(rect, seen.rect) : rect;
      if (clip.empty()) continue;
      auto [it, fresh] = reached.try_emplace(portal.neighbour, clip);
      if (!fresh) {
        if (it->second.contains(clip)) continue;
        it->second = unite(it->second, clip);
      }
      work.push_back(portal.neighbour);
    }
  }
  return reached;
}

// Points the bound vertex array's instance attributes (formation.vert's i_root, i_size, i_form,
// i_turn: 16 floats an instance) at instance `first` of the bound GL_ARRAY_BUFFER. (GL 4.1 has no
// base instance for instanced draws.)
void bind_instances(size_t first) {
  const size_t stride = 16 * sizeof(float);
  for (GLuint k = 0; k < 4; ++k)
    glVertexAttribPointer(1 + k, 4, GL_FLOAT, GL_FALSE, static_cast<GLsizei>(stride),
                          reinterpret_cast<const void*>(first * stride + k * 4 * sizeof(float)));
}

}  // namespace

Renderer::RoomLights Renderer::lights_reaching(std::span<const Light* const> points,
                                               const cave::Room& room, Vec3 camera, double reach) {
  RoomLights r;
  for (size_t i = 0; i < points.size(); ++i) {
    const Light& l = *points[i];
    const bool bounded = l.bound_radius > 0;
    const bool shades =
        length(l.position - room.sphere.centre) < l.range + reach &&
        (!bounded || length(l.bound_centre - room.sphere.centre) < l.bound_radius + reach);
    const bool hazes = !bounded || length(l.bound_centre - camera) < l.bound_radius;
    if (shades) {
      // Through a portal of the light's room: its light reaches the first metres in.
      const bool through =
          l.room && std::any_of(room.portals.begin(), room.portals.end(),
                                [&](const cave::Portal& p) { return p.neighbour == *l.room; });
      r.next_door[static_cast<size_t>(r.shade_count)] = through ? 1.0f : 0.0f;
      r.shading[static_cast<size_t>(r.shade_count++)] = static_cast<GLint>(i);
    }
    if (shades || hazes) r.hazing[static_cast<size_t>(r.haze_count++)] = static_cast<GLint>(i);
  }
  return r;
}

void Renderer::set_room_lights(const RoomUniforms& u, const RoomLights& lights) {
  glUniform1i(u.light_count, lights.shade_count);
  glUniform1iv(u.light_index, static_cast<GLsizei>(kMaxFrameLights), lights.shading.data());
  glUniform1fv(u.light_next_door, static_cast<GLsizei>(kMaxFrameLights), lights.next_door.data());
  glUniform1i(u.haze_count, lights.haze_count);
  glUniform1iv(u.haze_index, static_cast<GLsizei>(kMaxFrameLights), lights.hazing.data());
}

Renderer::RoomUniforms Renderer::locate(const Program& p) {
  return {
      p.uniform("u_room_offset"),    p.uniform("u_relief_margin"), p.uniform("u_camera"),
      p.uniform("u_max_tess"),       p.uniform("u_max_dist"),      p.uniform("u_view_proj"),
      p.uniform("u_block"),          p.uniform("u_surface"),       p.uniform("u_phong_alpha"),
      p.uniform("u_displacement"),   p.uniform("u_fog_color"),     p.uniform("u_fog_start"),
      p.uniform("u_fog_end"),        p.uniform("u_lamp_range"),    p.uniform("u_lod"),
      p.uniform("u_pixel_scale"),    p.uniform("u_target_pixels"), p.uniform("u_patch_culling"),
      p.uniform("u_frustum"),        p.uniform("u_fine_detail"),   p.uniform("u_ao"),
      p.uniform("u_lamp"),           p.uniform("u_forward"),       p.uniform("u_exposure"),
      p.uniform("u_glow"),           p.uniform("u_light_count"),   p.uniform("u_light_position"),
      p.uniform("u_light_color"),    p.uniform("u_light_glow"),    p.uniform("u_light_bound"),
      p.uniform("u_light_index"),    p.uniform("u_headlamp"),      p.uniform("u_haze"),
      p.uniform("u_patch_edge"),     p.uniform("u_haze_count"),    p.uniform("u_haze_index"),
      p.uniform("u_light_next_door")};
}

void Renderer::draw_formations(const std::vector<DrawnRoom>& rooms, Vec3 anchor, glm::vec3 eye,
                               const std::array<glm::vec4, 6>& planes, float pixel_scale,
                               FrameStats& stats) {
  // Per instance: 16 floats (formation.vert's i_root, i_size, i_form, i_turn), anchor-relative,
  // grouped by room and, in a room, by level of detail: one draw a group, lit by its room's lights.
  struct Batch {
    size_t room;
    int lod;
    size_t first;  // instance
    GLsizei count;
  };
  std::vector<float> data;
  std::vector<Batch> batches;
  std::array<std::vector<float>, kFormationLods> lods;
  for (size_t r = 0; r < rooms.size(); ++r) {
    const GpuRoom& room = *rooms[r].room;
    const glm::vec3 offset = to_vec3(room.origin - anchor);  // exact: grid values
    for (std::vector<float>& lod : lods)
      lod.clear();
    for (const formations::FormationShape& f : room.formations) {
      const glm::vec3 root = f.root + offset;
      const glm::vec3 centre = formations::formation_centre(f) + offset;
      const float reach = formations::formation_reach(f);
      bool outside = false;
      for (const glm::vec4& p : planes)
        outside = outside || glm::dot(glm::vec3(p), centre) + p.w < -reach;
      if (outside) continue;
      const int l = formations::lod_for(f, glm::distance(centre, eye) - reach, pixel_scale);
      if (l < 0) continue;
      lods[static_cast<size_t>(l)].insert(
          lods[static_cast<size_t>(l)].end(),
          {root.x, root.y, root.z, f.length, f.radius, f.tip, f.embed, static_cast<float>(f.kind),
           f.taper, f.flare, f.rings, f.bulbs, f.seed, f.yaw, f.tint, f.wet});
    }
    for (int l = 0; l < kFormationLods; ++l) {
      const std::vector<float>& lod = lods[static_cast<size_t>(l)];
      if (lod.empty()) continue;
      batches.push_back({r, l, data.size() / 16, static_cast<GLsizei>(lod.size() / 16)});
      data.insert(data.end(), lod.begin(), lod.end());
    }
  }
  if (batches.empty()) return;
  glBindBuffer(GL_ARRAY_BUFFER, formation_instances_.get());
  glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(data.size() * sizeof(float)), data.data(),
               GL_STREAM_DRAW);
  size_t lit = rooms.size();  // the room whose lights are set
  for (const Batch& b : batches) {
    if (b.room != lit) {
      set_room_lights(uf_, rooms[b.room].lights);
      lit = b.room;
    }
    const FormationLod& lod = formation_lods_[b.lod];
    glBindVertexArray(lod.vertex_array.get());
    bind_instances(b.first);
    glDrawElementsInstanced(GL_TRIANGLES, lod.index_count, GL_UNSIGNED_INT, nullptr, b.count);
    stats.formations += b.count;
    stats.formation_triangles +=
        static_cast<size_t>(b.count) * static_cast<size_t>(lod.index_count / 3);
  }
  glBindVertexArray(0);
}

const char* lod_heuristic_name(LodHeuristic lod) {
  switch (lod) {
    case LodHeuristic::kDistance:
      return "distance";
    case LodHeuristic::kScreenSpace:
      return "screen-space";
    case LodHeuristic::kSilhouette:
      return "silhouette";
  }
  return "?";
}

Vec3 camera_forward(const Camera& c) {
  double pitch = std::clamp(c.pitch, -kMaxPitch, kMaxPitch);
  return {std::sin(c.yaw) * std::cos(pitch), std::sin(pitch), -std::cos(c.yaw) * std::cos(pitch)};
}

Vec3 render_anchor(Vec3 p) {
  return {std::floor(p.x / kAnchorStep) * kAnchorStep, std::floor(p.y / kAnchorStep) * kAnchorStep,
          std::floor(p.z / kAnchorStep) * kAnchorStep};
}

Result<Renderer> Renderer::create() {
  Renderer r;
  auto room = Program::build(room_stages());
  if (!room.ok()) return room.error();
  r.room_ = std::move(room).value();
  auto cap = Program::build(cap_stages());
  if (!cap.ok()) return cap.error();
  r.cap_ = std::move(cap).value();
  r.u_ = locate(r.room_);
  auto formation = Program::build(formation_stages());
  if (!formation.ok()) return formation.error();
  r.formation_ = std::move(formation).value();
  r.uf_ = locate(r.formation_);
  // The formations' meshes, finest first: sides round the axis, rings along it.
  r.formation_instances_ = make_buffer();
  for (int l = 0; l < kFormationLods; ++l) {
    FormationLod& lod = r.formation_lods_[l];
    lod.sides = formations::kLodSides[l];
    lod.rings = formations::kLodRings[l];
    std::vector<float> grid;
    for (int i = 0; i <= lod.rings; ++i)
      for (int k = 0; k <= lod.sides; ++k)  // the seam's column twice: the angle runs 0 to 2 pi
        grid.insert(grid.end(), {static_cast<float>(i) / static_cast<float>(lod.rings),
                                 static_cast<float>(2 * kPi * k / lod.sides)});
    std::vector<uint32_t> indices;
    const uint32_t row = static_cast<uint32_t>(lod.sides + 1);
    for (uint32_t i = 0; i < static_cast<uint32_t>(lod.rings); ++i)
      for (uint32_t k = 0; k < static_cast<uint32_t>(lod.sides); ++k) {
        const uint32_t a0 = i * row + k, a1 = a0 + 1, b0 = a0 + row, b1 = b0 + 1;
        indices.insert(indices.end(), {a0, b0, b1, a0, b1, a1});
      }
    lod.vertex_array = make_vertex_array();
    glBindVertexArray(lod.vertex_array.get());
    lod.grid = make_static_buffer(GL_ARRAY_BUFFER, grid.data(), grid.size() * sizeof(float));
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 2, GL_FLOAT, GL_FALSE, 2 * sizeof(float), nullptr);
    lod.indices = make_static_buffer(GL_ELEMENT_ARRAY_BUFFER, indices.data(),
                                     indices.size() * sizeof(uint32_t));
    lod.index_count = static_cast<GLsizei>(indices.size());
    glBindBuffer(GL_ARRAY_BUFFER, r.formation_instances_.get());
    for (GLuint k = 0; k < 4; ++k) {
      glEnableVertexAttribArray(1 + k);
      glVertexAttribDivisor(1 + k, 1);
    }
    bind_instances(0);
    glBindVertexArray(0);
  }
  for (Query& q : r.queries_) {
    GLuint n = 0;
    glGenQueries(1, &n);
    q = Query(n);
  }
  auto bloom = Program::build(bloom_stages());
  if (!bloom.ok()) return bloom.error();
  r.bloom_ = std::move(bloom).value();
  r.ub_ = {r.bloom_.uniform("u_source"), r.bloom_.uniform("u_texel"),
           r.bloom_.uniform("u_downsample"), r.bloom_.uniform("u_offset")};
  auto composite = Program::build(composite_stages());
  if (!composite.ok()) return composite.error();
  r.composite_ = std::move(composite).value();
  const Program& c = r.composite_;
  r.uc_ = {c.uniform("u_scene"),
           c.uniform("u_depth"),
           c.uniform("u_bloom"),
           c.uniform("u_bloom_strength"),
           c.uniform("u_motion"),
           c.uniform("u_max_blur"),
           c.uniform("u_inverse_view_proj"),
           c.uniform("u_previous_view_proj")};
  r.post_vertex_array_ = make_vertex_array();
  r.cap_view_proj_ = r.cap_.uniform("u_view_proj");
  r.cap_fog_color_ = r.cap_.uniform("u_fog_color");
  r.cap_vertex_array_ = make_vertex_array();
  r.cap_vertices_ = make_buffer();
  glBindVertexArray(r.cap_vertex_array_.get());
  glBindBuffer(GL_ARRAY_BUFFER, r.cap_vertices_.get());
  glEnableVertexAttribArray(0);
  glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 3 * sizeof(float), nullptr);
  glBindVertexArray(0);
  return r;
}

FrameStats Renderer::draw(const GpuRoomCache& cache, const Camera& camera, int width, int height,
                          const RenderOptions& o, std::span<const Light> scene_lights) {
  FrameStats stats;
  const Vec3 anchor = render_anchor(camera.position);
  const glm::vec3 eye = to_vec3(camera.position - anchor);
  const glm::vec3 forward = to_vec3(camera_forward(camera));
  const glm::mat4 view = glm::lookAt(eye, eye + forward, glm::vec3(0, 1, 0));
  const float aspect = height > 0 ? static_cast<float>(width) / static_cast<float>(height) : 1.0f;
  const glm::mat4 proj =
      glm::perspective(static_cast<float>(camera.fov_y), aspect, o.near_plane, o.far_plane);
  const glm::mat4 view_proj = proj * view;

  // Post passes draw the scene into textures first, then into the framebuffer bound on entry.
  GLint target = 0;
  glGetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &target);
  const bool post = (o.bloom || o.motion_blur) && width > 0 && height > 0;
  if (post) {
    if (Status made = ensure_post_targets(width, height); made.ok()) {
      glBindFramebuffer(GL_FRAMEBUFFER, post_.scene.get());
      glViewport(0, 0, width, height);
    } else {
      static bool told = false;  // once: the frame is drawn without post passes
      if (!told)
        std::fprintf(stderr, "grotto-client: no post passes: %s\n", made.error().message.c_str());
      told = true;
    }
  }
  const bool posting = post && post_.width == width && post_.height == height;
  last_scene_.framebuffer = posting ? post_.scene.get() : static_cast<GLuint>(target);
  last_scene_.width = width;
  last_scene_.height = height;
  last_scene_.near_plane = o.near_plane;
  last_scene_.far_plane = o.far_plane;
  last_scene_.fog_end = o.fog_end;
  last_scene_.tan_half_fov_y = std::tan(static_cast<float>(camera.fov_y) / 2);
  last_scene_.aspect = aspect;

  glClearColor(o.clear_color.r, o.clear_color.g, o.clear_color.b, 1.0f);
  glClearDepth(1.0);
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  glDisable(GL_CULL_FACE);  // rooms are seen from inside; a thin wall may show its back
  glPolygonMode(GL_FRONT_AND_BACK, o.wireframe ? GL_LINE : GL_FILL);

  const float relief = o.tessellation ? std::max(o.displacement, 0.0f) : 0.0f;
  // frame_lights: the headlamp first when on (room.frag's own lamp), then the point lights of
  // shaders/lights.glsl.
  const std::vector<Light> lights = frame_lights(camera, o, scene_lights);
  const bool headlamp = !lights.empty() && lights.front().kind == "headlamp";
  std::vector<const Light*> points;
  std::array<glm::vec4, kMaxFrameLights> light_position{}, light_color{}, light_glow{},
      light_bound{};
  for (size_t i = headlamp ? 1 : 0; i < lights.size() && points.size() < kMaxFrameLights; ++i) {
    const Light& l = lights[i];
    const size_t n = points.size();
    light_position[n] = glm::vec4(to_vec3(l.position - anchor), std::max(l.range, 1e-3f));
    light_color[n] = glm::vec4(l.colour, 0.0f);
    light_glow[n] =
        glm::vec4(l.size, static_cast<float>(l.glow), cave::light_pattern_seed(l.position),
                  std::max(l.source_radius, 0.05f));
    light_bound[n] = glm::vec4(to_vec3(l.bound_centre - anchor), std::max(l.bound_radius, 0.0f));
    points.push_back(&l);
  }
  const float pixel_scale =
      static_cast<float>(height) / (2.0f * std::tan(static_cast<float>(camera.fov_y) / 2));
  auto planes = frustum_planes(view_proj);
  std::array<glm::vec4, 6> unit_planes;
  for (size_t k = 0; k < planes.size(); ++k)
    unit_planes[k] = planes[k] / glm::length(glm::vec3(planes[k]));
  // What room.frag (and the stages before it) read, the same in the rooms' and the formations'
  // programs.
  auto set_frame = [&](const RoomUniforms& u) {
    glUniformMatrix4fv(u.view_proj, 1, GL_FALSE, glm::value_ptr(view_proj));
    glUniform3fv(u.camera, 1, glm::value_ptr(eye));
    // The anchor as the relief's block: render_anchor's step is kReliefBlock (1024 m), so the
    // anchor is a block's corner.
    assert(kAnchorStep == relief::kReliefBlock);
    glUniform3i(u.block, static_cast<GLint>(std::lround(anchor.x / relief::kReliefBlock)),
                static_cast<GLint>(std::lround(anchor.y / relief::kReliefBlock)),
                static_cast<GLint>(std::lround(anchor.z / relief::kReliefBlock)));
    glUniform1f(u.max_tess, o.tessellation ? std::clamp(o.max_tess, 1.0f, 64.0f) : 1.0f);
    glUniform1f(u.max_dist, std::max(o.max_dist, 1e-3f));
    glUniform1i(u.surface, o.tessellation ? static_cast<int>(o.surface) : 0);
    glUniform1f(u.phong_alpha, o.phong_alpha);
    glUniform1f(u.displacement, relief);
    glUniform3fv(u.fog_color, 1, glm::value_ptr(o.fog_color));
    glUniform1f(u.fog_start, o.fog_start);
    glUniform1f(u.fog_end, o.fog_end);
    glUniform1f(u.lamp_range, o.lamp_range);
    glUniform1f(u.fine_detail, std::max(o.fine_detail, 0.0f));
    glUniform1f(u.ao, o.ambient_occlusion ? 1.0f : 0.0f);
    glUniform1f(u.exposure, o.exposure);
    glUniform1f(u.glow, o.glow);
    glUniform3fv(u.forward, 1, glm::value_ptr(forward));
    glUniform1f(u.headlamp, headlamp ? 1.0f : 0.0f);
    if (headlamp)
      glUniform3fv(u.lamp, 1, glm::value_ptr(to_vec3(lights.front().position - anchor)));
    if (!points.empty()) {
      glUniform4fv(u.light_position, static_cast<GLsizei>(kMaxFrameLights),
                   glm::value_ptr(light_position[0]));
      glUniform4fv(u.light_color, static_cast<GLsizei>(kMaxFrameLights),
                   glm::value_ptr(light_color[0]));
      glUniform4fv(u.light_glow, static_cast<GLsizei>(kMaxFrameLights),
                   glm::value_ptr(light_glow[0]));
      glUniform4fv(u.light_bound, static_cast<GLsizei>(kMaxFrameLights),
                   glm::value_ptr(light_bound[0]));
      glUniform1f(u.haze, std::max(o.haze, 0.0f));
    }
    glUniform1i(u.lod, static_cast<int>(o.lod));
    glUniform1f(u.pixel_scale, pixel_scale);
    glUniform1f(u.target_pixels, std::max(o.target_pixels, 0.5f));
    glUniform1i(u.patch_culling, o.patch_culling ? 1 : 0);
    glUniform4fv(u.frustum, 6, glm::value_ptr(unit_planes[0]));
  };
  // The passes' GPU times (FrameStats::passes), one query at a time.
  const bool timing = o.gpu_timing && queries_[0];
  auto begin_pass = [&](int k) {
    if (timing) glBeginQuery(GL_TIME_ELAPSED, queries_[k].get());
  };
  auto end_pass = [&]() {
    if (timing) glEndQuery(GL_TIME_ELAPSED);
  };
  room_.use();
  set_frame(u_);
  begin_pass(0);
  glPatchParameteri(GL_PATCH_VERTICES, 3);

  // Rooms whose sphere is outside the frustum are skipped. Every vertex of a room lies in its
  // sphere up to vertex_sphere_margin (client/stream/verify.hpp checks it on arrival); PN bulges
  // (0.5 m) and the relief along the normal push surface points out by less than `margin`
  // more. The formations are culled one by one (draw_formations).
  const float margin = relief::relief_bound(relief) + 0.5f;
  std::map<cave::RoomId, ScreenRect> reached;
  if (o.portal_culling) {
    reached = reach_through_portals(cache, camera.position, anchor, view_proj, o.near_plane, margin,
                                    stats);
    stats.camera_located = !reached.empty();
  }
  std::vector<float> caps;
  std::vector<DrawnRoom> drawn;
  // Nearest first (by the distance to the room's sphere): the rock in front fills the depth buffer
  // before the rock behind it is shaded, so early depth testing skips most hidden fragments (the
  // rooms reached through portals overlap on screen).
  std::vector<std::pair<double, const std::pair<const cave::RoomId, GpuRoom>*>> order;
  order.reserve(cache.size());
  for (const auto& entry : cache.rooms()) {
    const cave::Sphere& sphere = entry.second.room.sphere;
    order.emplace_back(std::max(length(sphere.centre - camera.position) - sphere.radius, 0.0),
                       &entry);
  }
  std::stable_sort(order.begin(), order.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  for (const auto& [distance, entry] : order) {
    const cave::RoomId id = entry->first;
    const GpuRoom& room = entry->second;
    const ScreenRect* rect = nullptr;
    if (stats.camera_located) {
      auto it = reached.find(id);
      if (it == reached.end()) continue;
      rect = &it->second;
    }
    ++stats.rooms_reached;
    if (o.fog_caps) {
      for (const cave::Portal& portal : room.room.portals) {
        if (cache.contains(portal.neighbour)) continue;
        if (rect != nullptr) {
          const PortalView seen = view_portal(portal, anchor, view_proj, o.near_plane, margin);
          if (seen.kind == PortalView::kHidden) continue;
          if (seen.kind == PortalView::kRect && intersect(*rect, seen.rect).empty()) continue;
        }
        append_cap(portal, anchor, caps);
        ++stats.caps;
      }
    }
    const glm::vec3 centre = to_vec3(room.room.sphere.centre - anchor);
    const double radius =
        room.room.sphere.radius + stream::vertex_sphere_margin(room.room.sphere.radius);
    if (o.room_culling && sphere_outside(planes, centre, static_cast<float>(radius), margin)) {
      ++stats.rooms_culled;
      continue;
    }
    // Exact: origin and anchor are wire-grid values within 65,536 m of each other.
    glUniform3fv(u_.room_offset, 1, glm::value_ptr(to_vec3(room.origin - anchor)));
    glUniform1f(u_.relief_margin, relief::relief_bound(relief));
    glUniform1f(u_.patch_edge, room.patch_edge);
    const RoomLights room_lights =
        lights_reaching(points, room.room, camera.position, radius + margin);
    set_room_lights(u_, room_lights);
    glBindVertexArray(room.vertex_array.get());
    glDrawElements(GL_PATCHES, room.index_count, GL_UNSIGNED_INT, nullptr);
    ++stats.rooms_drawn;
    stats.patches += static_cast<size_t>(room.index_count) / 3;
    if (o.formations) drawn.push_back({&room, room_lights});
  }
  end_pass();

  // The formations of the rooms drawn, each culled and given its level of detail by its size on
  // screen.
  begin_pass(1);
  if (!drawn.empty()) {
    formation_.use();
    set_frame(uf_);
    draw_formations(drawn, anchor, eye, unit_planes, pixel_scale, stats);
  }
  end_pass();
  begin_pass(2);

  if (!caps.empty()) {
    cap_.use();
    glUniformMatrix4fv(cap_view_proj_, 1, GL_FALSE, glm::value_ptr(view_proj));
    glUniform3fv(cap_fog_color_, 1, glm::value_ptr(o.fog_color));
    glBindVertexArray(cap_vertex_array_.get());
    glBindBuffer(GL_ARRAY_BUFFER, cap_vertices_.get());
    glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(caps.size() * sizeof(float)), caps.data(),
                 GL_STREAM_DRAW);
    // Caps are fog, not rock: tested against the rooms' depth (drawn before them) but writing
    // none, so read_view_depth sees through them. The picture is the same: a cap is one colour.
    glDepthMask(GL_FALSE);
    glDrawArrays(GL_TRIANGLES, 0, static_cast<GLsizei>(caps.size() / 3));
    glDepthMask(GL_TRUE);
  }
  end_pass();
  glBindVertexArray(0);
  glPolygonMode(GL_FRONT_AND_BACK, GL_FILL);

  // Motion blur follows the camera from the last frame, unless it jumped (a cut).
  const Vec3 moved = camera.position - previous_camera_.position;
  stats.motion_cut = !has_previous_ || length(moved) > kCutDistance ||
                     std::abs(camera.yaw - previous_camera_.yaw) > kCutAngle ||
                     std::abs(camera.pitch - previous_camera_.pitch) > kCutAngle;
  // Last frame's view-projection moved into this frame's anchor-relative space.
  const glm::mat4 previous =
      stats.motion_cut ? view_proj
                       : previous_view_proj_ *
                             glm::translate(glm::mat4(1.0f), to_vec3(anchor - previous_anchor_));
  begin_pass(3);
  if (posting) post_process(target, width, height, view_proj, previous, o);
  end_pass();
  if (timing) {
    double* out[4] = {&stats.passes.rock, &stats.passes.formations, &stats.passes.caps,
                      &stats.passes.post};
    for (int k = 0; k < 4; ++k) {
      GLuint64 ns = 0;
      glGetQueryObjectui64v(queries_[k].get(), GL_QUERY_RESULT, &ns);
      *out[k] = static_cast<double>(ns) * 1e-6;
    }
    stats.passes.timed = true;
  }
  has_previous_ = true;
  previous_camera_ = camera;
  previous_view_proj_ = view_proj;
  previous_anchor_ = anchor;
  return stats;
}

std::vector<Light> frame_lights(const Camera& camera, const RenderOptions& options,
                                std::span<const Light> scene) {
  std::vector<Light> out;
  if (options.headlamp) {
    // The headlamp sits on the forehead, a little right of the eye: shading shows the relief.
    const Vec3 forward = camera_forward(camera);
    Vec3 right = cross(forward, Vec3{0, 1, 0});
    const double l = length(right);
    right = l > 1e-9 ? right / l : Vec3{std::cos(camera.yaw), 0, std::sin(camera.yaw)};
    out.push_back(Light{"headlamp", camera.position + right * 0.25 + Vec3{0, 0.3, 0}});
  }
  // A light lights the frame when its range reaches rock nearer than the fog's end.
  struct Pick {
    bool world;  // flares first
    double distance;
    size_t index;
  };
  std::vector<Pick> picks;
  const double fog_end = options.fog_end;
  for (size_t i = 0; i < scene.size(); ++i) {
    const Light& l = scene[i];
    const double d = length(l.position - camera.position);
    if (d >= l.range + fog_end) continue;
    if (l.bound_radius > 0 && length(l.bound_centre - camera.position) >= l.bound_radius + fog_end)
      continue;
    picks.push_back({l.kind != "flare", d, i});
  }
  std::sort(picks.begin(), picks.end(), [](const Pick& a, const Pick& b) {
    return std::tie(a.world, a.distance, a.index) < std::tie(b.world, b.distance, b.index);
  });
  for (size_t i = 0; i < picks.size() && i < kMaxFrameLights; ++i)
    out.push_back(scene[picks[i].index]);
  return out;
}

std::vector<float> Renderer::read_view_depth() const {
  const SceneDepth& d = last_scene_;
  if (d.width <= 0 || d.height <= 0) return {};
  const size_t w = static_cast<size_t>(d.width), h = static_cast<size_t>(d.height);
  std::vector<float> raw(w * h);
  GLint previous = 0;
  glGetIntegerv(GL_READ_FRAMEBUFFER_BINDING, &previous);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, d.framebuffer);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadPixels(0, 0, d.width, d.height, GL_DEPTH_COMPONENT, GL_FLOAT, raw.data());
  glBindFramebuffer(GL_READ_FRAMEBUFFER, static_cast<GLuint>(previous));
  std::vector<float> out(w * h, std::numeric_limits<float>::infinity());
  const double n = d.near_plane, f = d.far_plane;
  for (size_t y = 0; y < h; ++y) {
    // GL's rows start at the bottom; out's at the top.
    const float* row = raw.data() + (h - 1 - y) * w;
    const double ndc_y = 1.0 - 2.0 * (static_cast<double>(y) + 0.5) / static_cast<double>(h);
    for (size_t x = 0; x < w; ++x) {
      const double depth = row[x];
      if (!(depth < 1.0)) continue;  // cleared: nothing drawn here
      // glm::perspective's depth: z_ndc = (f + n) / (f - n) - 2 f n / ((f - n) z_eye).
      const double z_ndc = 2.0 * depth - 1.0;
      const double z = 2.0 * f * n / (f + n - z_ndc * (f - n));
      const double ndc_x = 2.0 * (static_cast<double>(x) + 0.5) / static_cast<double>(w) - 1.0;
      const double sx = ndc_x * d.tan_half_fov_y * d.aspect, sy = ndc_y * d.tan_half_fov_y;
      // room.frag fogs by the distance from the eye: wholly fogged from fog_end on.
      if (z * std::sqrt(1.0 + sx * sx + sy * sy) >= d.fog_end) continue;
      out[y * w + x] = static_cast<float>(z);
    }
  }
  return out;
}

Status Renderer::ensure_post_targets(int width, int height) {
  if (post_.width == width && post_.height == height) return {};
  post_ = PostTargets{};
  auto texture = [](GLint internal, int w, int h, GLenum format, GLenum type) {
    Texture t = make_texture();
    glBindTexture(GL_TEXTURE_2D, t.get());
    glTexImage2D(GL_TEXTURE_2D, 0, internal, w, h, 0, format, type, nullptr);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    return t;
  };
  auto framebuffer = [](GLuint color, GLuint depth) -> Result<FramebufferName> {
    GLuint n = 0;
    glGenFramebuffers(1, &n);
    FramebufferName f(n);
    glBindFramebuffer(GL_FRAMEBUFFER, n);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, color, 0);
    if (depth != 0)
      glFramebufferTexture2D(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_TEXTURE_2D, depth, 0);
    const GLenum status = glCheckFramebufferStatus(GL_FRAMEBUFFER);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    if (status != GL_FRAMEBUFFER_COMPLETE)
      return Error{ErrorCode::kUnavailable,
                   "post-pass framebuffer incomplete (status 0x" + std::to_string(status) + ")"};
    return f;
  };
  PostTargets t;
  t.scene_color = texture(GL_RGBA8, width, height, GL_RGBA, GL_UNSIGNED_BYTE);
  t.scene_depth = texture(GL_DEPTH_COMPONENT24, width, height, GL_DEPTH_COMPONENT, GL_UNSIGNED_INT);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  auto scene = framebuffer(t.scene_color.get(), t.scene_depth.get());
  if (!scene.ok()) return scene.error();
  t.scene = std::move(scene).value();
  const int bw = std::max(1, width / 4), bh = std::max(1, height / 4);
  for (int i = 0; i < 2; ++i) {
    t.bloom_color[i] = texture(GL_RGBA8, bw, bh, GL_RGBA, GL_UNSIGNED_BYTE);
    auto f = framebuffer(t.bloom_color[i].get(), 0);
    if (!f.ok()) return f.error();
    t.bloom[i] = std::move(f).value();
  }
  glBindTexture(GL_TEXTURE_2D, 0);
  t.width = width;
  t.height = height;
  post_ = std::move(t);
  return {};
}

void Renderer::post_process(GLint target, int width, int height, const glm::mat4& view_proj,
                            const glm::mat4& previous_view_proj, const RenderOptions& o) {
  glDisable(GL_DEPTH_TEST);
  glBindVertexArray(post_vertex_array_.get());
  const int bw = std::max(1, width / 4), bh = std::max(1, height / 4);
  // Bloom: the glow downsampled to a quarter, then Kawase passes ping-ponging between two targets.
  int last = 0;
  const bool bloom = o.bloom && o.bloom_strength > 0;
  if (bloom) {
    bloom_.use();
    glUniform1i(ub_.source, 0);
    glActiveTexture(GL_TEXTURE0);
    glViewport(0, 0, bw, bh);
    glBindFramebuffer(GL_FRAMEBUFFER, post_.bloom[0].get());
    glBindTexture(GL_TEXTURE_2D, post_.scene_color.get());
    glUniform2f(ub_.texel, 1.0f / static_cast<float>(width), 1.0f / static_cast<float>(height));
    glUniform1i(ub_.downsample, 1);
    glDrawArrays(GL_TRIANGLES, 0, 3);
    glUniform1i(ub_.downsample, 0);
    glUniform2f(ub_.texel, 1.0f / static_cast<float>(bw), 1.0f / static_cast<float>(bh));
    static constexpr float kOffsets[] = {0, 1, 2, 2, 3, 4, 5};
    const int passes = std::clamp(o.bloom_passes, 1, 7);
    for (int i = 0; i < passes; ++i) {
      glBindFramebuffer(GL_FRAMEBUFFER, post_.bloom[1 - last].get());
      glBindTexture(GL_TEXTURE_2D, post_.bloom_color[last].get());
      glUniform1f(ub_.offset, kOffsets[i]);
      glDrawArrays(GL_TRIANGLES, 0, 3);
      last = 1 - last;
    }
  }
  // The composite into the caller's framebuffer.
  glBindFramebuffer(GL_FRAMEBUFFER, static_cast<GLuint>(target));
  glViewport(0, 0, width, height);
  composite_.use();
  glUniform1i(uc_.scene, 0);
  glUniform1i(uc_.depth, 1);
  glUniform1i(uc_.bloom, 2);
  glActiveTexture(GL_TEXTURE0);
  glBindTexture(GL_TEXTURE_2D, post_.scene_color.get());
  glActiveTexture(GL_TEXTURE1);
  glBindTexture(GL_TEXTURE_2D, post_.scene_depth.get());
  glActiveTexture(GL_TEXTURE2);
  glBindTexture(GL_TEXTURE_2D, post_.bloom_color[last].get());
  glUniform1f(uc_.bloom_strength, bloom ? o.bloom_strength : 0.0f);
  glUniform1f(uc_.motion, o.motion_blur ? o.motion_blur_strength : 0.0f);
  glUniform2f(uc_.max_blur, o.motion_blur_max,
              o.motion_blur_max * static_cast<float>(width) / static_cast<float>(height));
  const glm::mat4 inverse = glm::inverse(view_proj);
  glUniformMatrix4fv(uc_.inverse_view_proj, 1, GL_FALSE, glm::value_ptr(inverse));
  glUniformMatrix4fv(uc_.previous_view_proj, 1, GL_FALSE, glm::value_ptr(previous_view_proj));
  glDrawArrays(GL_TRIANGLES, 0, 3);
  glActiveTexture(GL_TEXTURE0);
  glBindTexture(GL_TEXTURE_2D, 0);
  glBindVertexArray(0);
  glEnable(GL_DEPTH_TEST);
}

}  // namespace grotto::render
