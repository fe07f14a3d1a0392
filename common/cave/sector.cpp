// Sector generation: gates on the faces, a hub and gate links, then the thesis's growing tree.
#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdlib>
#include <optional>

#include "common/cave/layout.hpp"
#include "common/core/random.hpp"

namespace grotto::cave {
namespace {

constexpr uint64_t kFaceStream = 0x6761746573000001ull;    // "gates"
constexpr uint64_t kSectorStream = 0x736563746f720001ull;  // "sector"
constexpr uint64_t kHallStream = 0x68616c6c00000001ull;    // "hall": whether a sector has one
constexpr int kMaxAttempts = 10;
// A chain may add rooms enough to cross its sector a few times over, and try 15 per room.
int max_chain_rooms(const LayoutParams& p) {
  return std::max(40, static_cast<int>(3.0 * p.sector_size / p.link_radius_min));
}
constexpr int kFailsBeforeBacktrack = 10;
constexpr int kFailsBeforeDeadEnd = 8;
constexpr int kTriesPerGate = 32;
// Portal radius as a fraction of the smaller sphere's radius, at most. Links keep their portals
// small (half-angle <= ~37 degrees) so a link room has wall left for a third portal: with larger
// ones the two portals of a straight chain leave no room for a join.
constexpr double kLinkPortal = 0.45;
constexpr double kGrowPortal = 0.8;
// A loop bridge joins rooms at least this many portals apart, so every loop is worth walking.
constexpr int kMinLoopLength = 6;
constexpr int kLoopRooms = 8;   // rooms one loop chain may add
constexpr int kLoopTries = 80;  // candidates one loop chain may try
// Each centre stays at least this fraction of its radius behind a portal plane, so a portal never
// cuts through the middle of a room and the mesh stage always has a wall to deform.
constexpr double kMinPlaneDepth = 0.25;

Vec3 random_direction(Rng& rng) {
  for (;;) {
    Vec3 v{rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1)};
    double l2 = length_squared(v);
    if (l2 > 1e-6 && l2 <= 1.0) return v / std::sqrt(l2);
  }
}

struct Disc {
  Vec3 centre;
  Vec3 normal;  // from the first sphere towards the second
  double radius = 0;
};

// Thesis Figure 3-2: the plane of the overlap lies at pd from a's centre along the centre line
// (cosine rule), and the disc's radius follows from Pythagoras. Nothing when the overlap is too
// thin for a player or so deep that a centre is near the plane.
std::optional<Disc> overlap_disc(const Sphere& a, const Sphere& b, double min_radius) {
  Vec3 v = b.centre - a.centre;
  double d = length(v);
  double pd_a = (d * d + a.radius * a.radius - b.radius * b.radius) / (2.0 * d);
  double pd_b = d - pd_a;
  if (pd_a < kMinPlaneDepth * a.radius || pd_b < kMinPlaneDepth * b.radius) return std::nullopt;
  double r2 = a.radius * a.radius - pd_a * pd_a;
  if (r2 < min_radius * min_radius) return std::nullopt;
  Vec3 n = v / d;
  return Disc{a.centre + n * pd_a, n, std::sqrt(r2)};
}

// The centre distance at which spheres of radii r1 and r2 meet in a portal of radius a: each
// centre sits sqrt(r^2 - a^2) behind the portal plane. Choosing the portal first keeps every
// overlap valid whatever the two radii, so big rooms attach to small ones as often as the
// thesis's big-room probability asks.
double centre_distance(double r1, double r2, double a) {
  return std::sqrt(r1 * r1 - a * a) + std::sqrt(r2 * r2 - a * a);
}

// How far a disc's rim reaches above and below its centre.
double half_height(const Disc& disc) {
  return disc.radius * std::sqrt(std::max(0.0, 1.0 - disc.normal.y * disc.normal.y));
}

// True when the disc comes within the wall clearance of the floor of sphere s (its lowest point
// under the floor plane plus the clearance): the floor's undulation and its join with the wall
// stay clear of the rim.
bool below_floor(const LayoutParams& params, const Sphere& s, const Disc& disc) {
  std::optional<double> floor = floor_height(params, s);
  return floor && disc.centre.y - half_height(disc) < *floor + params.wall_clearance;
}

// True when the disc reaches above the spring of sphere s's ceiling: the mesh lowers the wall
// there, and a rim must stay where the layout put it.
bool above_spring(const LayoutParams& params, const Sphere& s, const Disc& disc) {
  std::optional<Ceiling> ceiling = room_ceiling(params, s);
  return ceiling && disc.centre.y + half_height(disc) > ceiling->spring;
}

double distance_to_disc(Vec3 p, const Disc& disc) {
  Vec3 rel = p - disc.centre;
  double h = dot(rel, disc.normal);
  double q = length(rel - disc.normal * h);
  double radial = q > disc.radius ? q - disc.radius : 0.0;
  return std::sqrt(h * h + radial * radial);
}

// The cap a portal cuts off a sphere, as the cone from the centre through the portal rim.
struct Cap {
  Vec3 axis;
  double cos_a, sin_a;
};

Cap cap_of(const Sphere& s, const Disc& disc) {
  Vec3 v = disc.centre - s.centre;
  double pd = length(v);
  return {v / pd, pd / s.radius, disc.radius / s.radius};
}

// Portals of one room never intersect and keep `gap` metres of wall between them: the angle
// between cap axes exceeds both half-angles plus asin(gap / R). Only +, -, *, / and sqrt, so the
// decision is the same on every machine.
bool caps_apart(const Cap& p, const Cap& q, double radius, double gap) {
  double cos_b = p.cos_a * q.cos_a - p.sin_a * q.sin_a;
  double sin_b = p.sin_a * q.cos_a + p.cos_a * q.sin_a;
  double sg = std::min(1.0, gap / radius);
  double cg = std::sqrt(1.0 - sg * sg);
  double cos_bg = cos_b * cg - sin_b * sg;
  double sin_bg = sin_b * cg + cos_b * sg;
  if (sin_bg < 0) return false;  // the caps with their gap span more than half the sphere
  return dot(p.axis, q.axis) < cos_bg;
}

struct Node {
  Sphere sphere;
  RoomId id;
  std::vector<int> edges;
};

struct Edge {
  int a, b;  // node indices; disc.normal points from a to b
  Disc disc;
};

// Grows one sector: gates first, then the chains that link them, then the growing tree.
class SectorBuilder {
 public:
  SectorBuilder(const LayoutParams& params, SectorCoord sector, const std::vector<Room>& gates)
      : params_(params), sector_(sector) {
    for (int a = 0; a < 3; ++a) {
      lo_[a] = sector[a] * params.sector_size;
      hi_[a] = lo_[a] + params.sector_size;
    }
    // Any two spheres that can interact are within one cell of each other.
    cell_ = 2.0 * max_room_radius(params) + std::max(params.wall_clearance, params.portal_gap);
    dim_ = static_cast<int>(std::ceil(params.sector_size / cell_)) + 2;
    fine_cell_ = std::max(kFineCell, params.sector_size / kMaxFineCells);
    fine_dim_ = static_cast<int>(std::ceil(params.sector_size / fine_cell_)) + 2;
    fine_.resize(static_cast<size_t>(fine_dim_) * fine_dim_ * fine_dim_);
    for (const Room& g : gates)
      add(g.sphere, g.id, {});
    gate_count_ = static_cast<int>(nodes_.size());
  }

  // Links every gate into one component: a hub room near the middle of the sector, then a chain
  // of overlapping spheres from each gate towards it. Chains come from different faces, so they
  // rarely meet before the hub, and a big hub has room for all their portals. False when a chain
  // ran out of tries (the caller retries with another stream).
  // hall_radius > 0: the hub is a hall of that radius.
  bool link_gates(Rng& rng, const Character& c, double hall_radius) {
    int root = place_hub(rng, c, hall_radius);
    if (root < 0) root = 0;
    for (int g = 0; g < gate_count_; ++g) {
      int head = g, fails = 0, rooms = 0, tries = 0;
      while (find(g) != find(root)) {
        if (rooms > max_chain_rooms(params_) || ++tries > 15 * max_chain_rooms(params_)) {
          return false;
        }
        const Sphere h = nodes_[head].sphere;
        // Aim at the hub from afar; near linked rooms, at one of the three nearest.
        int target = nearest_linked(h, find(root), rng.below(3));
        const Sphere t = nodes_[target].sphere;
        Sphere s;
        s.radius = rng.uniform(params_.link_radius_min, params_.link_radius_max);
        if (!bridge(h, t, rng, s)) {
          Vec3 towards = normalize(t.centre - h.centre) + away_from_faces(h.centre);
          Vec3 dir = normalize(normalize(towards) + random_direction(rng) * (0.3 + 0.1 * fails));
          double a = portal_radius(rng, h.radius, s.radius, kLinkPortal);
          s.centre = h.centre + dir * centre_distance(h.radius, s.radius, a);
        }
        s = shrink_to_clear(s);
        if (auto edges = try_place(s)) {
          head = add_interior(s, std::move(*edges));
          if (head < 0) return false;
          ++rooms;
          fails = 0;
        } else if (++fails >= kFailsBeforeBacktrack) {
          // Stuck: go on from another room of this chain's component.
          head = random_in_component(rng, find(g));
          fails = 0;
        }
      }
    }
    return true;
  }

  // Links may shrink to keep clear of a sphere they would nearly touch, down to the smallest link
  // radius: chains then slip past other chains instead of failing.
  Sphere shrink_to_clear(Sphere s) const {
    nearby(s, params_.wall_clearance, near_shrink_);
    for (int j : near_shrink_) {
      const Sphere& o = nodes_[j].sphere;
      double d = distance(s.centre, o.centre);
      bool near_miss = d >= s.radius + o.radius && d < s.radius + o.radius + params_.wall_clearance;
      if (near_miss)
        s.radius = std::max(params_.link_radius_min, d - o.radius - params_.wall_clearance);
    }
    return s;
  }

  // A random portal radius for two spheres: at least the minimum, at most `fraction` of the
  // smaller radius.
  double portal_radius(Rng& rng, double r1, double r2, double fraction) const {
    double hi = fraction * std::min(r1, r2);
    double lo = std::min(params_.min_portal_radius, hi);
    return rng.uniform(lo, hi);
  }

  // A sphere of s.radius that overlaps both h and t with link-sized portals: its
  // centre lies on the circle where two spheres around h and t meet, at a random angle, so that
  // retries come at the target from every side. False when h and t are too far apart.
  bool bridge(const Sphere& h, const Sphere& t, Rng& rng, Sphere& s) const {
    double d1 =
        centre_distance(h.radius, s.radius, portal_radius(rng, h.radius, s.radius, kLinkPortal));
    double d2 =
        centre_distance(t.radius, s.radius, portal_radius(rng, t.radius, s.radius, kLinkPortal));
    Vec3 axis = t.centre - h.centre;
    double dist = length(axis);
    if (dist >= d1 + d2 || dist <= std::abs(d1 - d2)) return false;
    axis = axis / dist;
    double along = (dist * dist + d1 * d1 - d2 * d2) / (2.0 * dist);
    double ring = std::sqrt(std::max(0.0, d1 * d1 - along * along));
    Vec3 side = random_direction(rng);
    side = side - axis * dot(side, axis);
    if (length_squared(side) < 1e-9) return false;
    s.centre = h.centre + axis * along + normalize(side) * ring;
    return true;
  }

  // The k-th nearest room (by gap between spheres) of component `root` to h; the hub when the
  // component is far away, so chains head for the middle of the sector.
  int nearest_linked(const Sphere& h, int root, uint32_t k) {
    std::vector<std::pair<double, int>> near;
    for (int i = 0; i < static_cast<int>(nodes_.size()); ++i) {
      if (find(i) != root) continue;
      double gap = distance(h.centre, nodes_[i].sphere.centre) - nodes_[i].sphere.radius;
      near.push_back({gap, i});
    }
    size_t n = std::min<size_t>(k, near.size() - 1);
    std::partial_sort(near.begin(), near.begin() + n + 1, near.end());
    return near[n].second;
  }

  // Chains leave a gate straight into the sector: a push away from every face the point is near
  // (within the space a gate and two link rooms take), zero in the middle of the sector.
  Vec3 away_from_faces(Vec3 p) const {
    double reach = params_.gate_radius_max + 2.0 * params_.link_radius_max;
    Vec3 push;
    for (int a = 0; a < 3; ++a) {
      if (p[a] - lo_[a] < reach) push[a] += 1.0;
      if (hi_[a] - p[a] < reach) push[a] -= 1.0;
    }
    return push;
  }

  // A big room in the middle half of the sector, clear of every gate; -1 when none fits. A hall
  // keeps hall_clearance from every face (validate() made the sector big enough), so a gate
  // anywhere on a face and a link room fit beside it.
  int place_hub(Rng& rng, const Character& c, double hall_radius) {
    const double size = params_.sector_size;
    const double lo = std::max(0.3 * size, hall_radius + hall_clearance(params_));
    const double hi =
        std::max(lo, std::min(0.7 * size, size - hall_radius - hall_clearance(params_)));
    for (int tries = 0; tries < 16; ++tries) {
      Sphere s;
      s.radius = rng.uniform(c.big_radius_min, c.big_radius_max);
      if (hall_radius > 0) s.radius = hall_radius;
      for (int a = 0; a < 3; ++a) {
        s.centre[a] = lo_[a] + (hall_radius > 0 ? lo + (hi - lo) * rng.uniform(0.0, 1.0)
                                                : size * rng.uniform(0.3, 0.7));
      }
      bool clear = true;
      nearby(s, params_.wall_clearance, near_hub_);
      for (int j : near_hub_) {
        const Sphere& o = nodes_[j].sphere;
        if (distance(s.centre, o.centre) < s.radius + o.radius + params_.wall_clearance) {
          clear = false;
        }
      }
      if (clear && inside_box(s)) return add_interior(s, {});
    }
    return -1;
  }

  // Thesis §3.1.2: pick a room (the most recent one with the tunnel chance), add an overlapping
  // sphere displaced along a biased random direction, keep it if every portal it makes is valid.
  void grow(Rng& rng, const Character& c) {
    int recent = nodes_.empty() ? -1 : static_cast<int>(nodes_.size()) - 1;
    std::vector<int> fails(nodes_.size(), 0);
    int added = 0;
    for (int tries = 0; added < c.room_count && tries < 40 * c.room_count; ++tries) {
      bool from_recent = recent >= 0 && rng.chance(c.tunnel_chance);
      int parent = from_recent ? recent : static_cast<int>(rng.below(nodes_.size()));
      double r = rng.chance(c.big_probability)
                     ? rng.uniform(c.big_radius_min, c.big_radius_max)
                     : rng.uniform(c.small_radius_min, c.small_radius_max);
      Vec3 biased = hadamard(random_direction(rng), c.bias);
      double pr = nodes_[parent].sphere.radius;
      double d = centre_distance(pr, r, portal_radius(rng, pr, r, kGrowPortal));
      if (length_squared(biased) <= 1e-12 * length_squared(c.bias)) continue;
      Sphere s{nodes_[parent].sphere.centre + normalize(biased) * d, r};
      if (auto edges = try_place(s)) {
        int added_index = add_interior(s, std::move(*edges));
        if (added_index < 0) return;
        recent = added_index;
        fails.push_back(0);
        ++added;
      } else if (from_recent && ++fails[parent] >= kFailsBeforeDeadEnd) {
        recent = -1;  // a dead end: the next room grows from anywhere and starts a new tunnel
      }
    }
  }

  // Extra passages between rooms that are near in space but far apart in the graph, so the cave
  // offers alternative routes (thesis §3.1.1: a graph, not a tree). Each loop is a short chain
  // of link rooms from a random room towards such a partner; a chain that cannot reach its
  // partner stays as a dead-end side tunnel.
  void close_loops(Rng& rng, int count) {
    for (int tries = 0, made = 0; made < count && tries < 4 * count; ++tries) {
      int a = static_cast<int>(rng.below(static_cast<uint32_t>(nodes_.size())));
      const Sphere sa = nodes_[a].sphere;
      std::vector<int> far;
      nearby(sa, 4.0 * params_.link_radius_max, near_loops_);
      for (int b : near_loops_) {
        if (b != a && hops_apart(a, b, kMinLoopLength)) far.push_back(b);
      }
      if (far.empty()) continue;
      int b = far[rng.below(static_cast<uint32_t>(far.size()))];
      made += chain_to(rng, a, b);
    }
  }

  // Walks a chain of link rooms from `from` until one overlaps `to`.
  bool chain_to(Rng& rng, int from, int to) {
    int head = from;
    for (int tries = 0, rooms = 0; tries < kLoopTries && rooms < kLoopRooms; ++tries) {
      const Sphere h = nodes_[head].sphere;
      const Sphere t = nodes_[to].sphere;
      Sphere s;
      s.radius = rng.uniform(params_.link_radius_min, params_.link_radius_max);
      if (!bridge(h, t, rng, s)) {
        Vec3 dir = normalize(normalize(t.centre - h.centre) + random_direction(rng) * 0.4);
        s.centre =
            h.centre + dir * centre_distance(h.radius, s.radius,
                                             portal_radius(rng, h.radius, s.radius, kLinkPortal));
      }
      s = shrink_to_clear(s);
      auto edges = try_place(s);
      if (!edges) continue;
      bool reached =
          std::any_of(edges->begin(), edges->end(), [to](const Edge& e) { return e.b == to; });
      head = add_interior(s, std::move(*edges));
      if (head < 0) return false;
      ++rooms;
      if (reached) return true;
    }
    return false;
  }

  // True when no path of fewer than `hops` portals joins a and b.
  bool hops_apart(int a, int b, int hops) {
    ++visit_stamp_;
    visited_.resize(nodes_.size(), 0);
    std::vector<int> frontier{a}, next;
    visited_[a] = visit_stamp_;
    for (int depth = 0; depth < hops - 1 && !frontier.empty(); ++depth) {
      next.clear();
      for (int n : frontier) {
        for (int e : nodes_[n].edges) {
          int m = edges_[e].a == n ? edges_[e].b : edges_[e].a;
          if (m == b) return false;
          if (visited_[m] != visit_stamp_) {
            visited_[m] = visit_stamp_;
            next.push_back(m);
          }
        }
      }
      std::swap(frontier, next);
    }
    return true;
  }

  int interior_count() const { return static_cast<int>(nodes_.size()) - gate_count_; }

  SectorLayout finish(const SectorCharacter& character, int attempts, int link_rooms) const {
    SectorLayout out;
    out.link_rooms = link_rooms;
    out.sector = sector_;
    out.character = character;
    out.attempts = attempts;
    int root = find_const(0);
    out.connected = true;
    for (size_t i = 0; i < nodes_.size(); ++i) {
      if (find_const(static_cast<int>(i)) != root) out.connected = false;
      Room room{nodes_[i].id, nodes_[i].sphere, {}};
      for (int e : nodes_[i].edges) {
        const Edge& edge = edges_[e];
        bool forward = edge.a == static_cast<int>(i);
        int other = forward ? edge.b : edge.a;
        Vec3 n = forward ? edge.disc.normal : -edge.disc.normal;
        room.portals.push_back({edge.disc.centre, n, edge.disc.radius, nodes_[other].id});
      }
      std::sort(room.portals.begin(), room.portals.end(),
                [](const Portal& p, const Portal& q) { return p.neighbour < q.neighbour; });
      (static_cast<int>(i) < gate_count_ ? out.gates : out.rooms).push_back(std::move(room));
    }
    return out;
  }

 private:
  // The edges a new sphere would make, or nothing when it breaks a rule: outside the sector box,
  // too close to a sphere it does not overlap, a portal too small or too deep, a portal disc
  // touching a third sphere, or two portals of one room too close.
  std::optional<std::vector<Edge>> try_place(const Sphere& s) const {
    if (!inside_box(s)) return std::nullopt;
    // Spheres farther than this cannot make or touch a portal of s (see the checks below).
    std::vector<int>& near = near_place_;
    nearby(s, std::max(params_.wall_clearance, params_.portal_gap), near);
    std::vector<Edge> made;
    for (int j : near) {
      const Sphere& o = nodes_[j].sphere;
      double d = distance(s.centre, o.centre);
      if (d >= s.radius + o.radius + params_.wall_clearance) continue;
      if (d >= s.radius + o.radius) return std::nullopt;
      auto disc = overlap_disc(s, o, params_.min_portal_radius);
      if (!disc) return std::nullopt;
      if (below_floor(params_, s, *disc) || below_floor(params_, o, *disc)) return std::nullopt;
      if (above_spring(params_, s, *disc) || above_spring(params_, o, *disc)) return std::nullopt;
      made.push_back({-1, j, *disc});
    }
    if (made.empty() || made.size() > static_cast<size_t>(kMaxPortalsPerRoom)) {
      return std::nullopt;
    }
    for (const Edge& m : made) {
      // A gate gets portals from both its sectors: each side may fill half of the limit.
      size_t limit = kMaxPortalsPerRoom / (m.b < gate_count_ ? 2 : 1);
      if (nodes_[m.b].edges.size() >= limit) return std::nullopt;
    }
    double gap = params_.portal_gap;
    // Never three spheres at one portal: the new sphere stays clear of existing discs ...
    for (int j : near) {
      for (int e : nodes_[j].edges) {
        if (distance_to_disc(s.centre, edges_[e].disc) <= s.radius + gap) return std::nullopt;
      }
    }
    // ... and its own discs stay clear of every sphere but their two.
    for (const Edge& m : made) {
      for (int k : near) {
        if (k == m.b) continue;
        const Sphere& o = nodes_[k].sphere;
        if (distance_to_disc(o.centre, m.disc) <= o.radius + gap) return std::nullopt;
      }
    }
    for (size_t i = 0; i < made.size(); ++i) {
      Cap ci = cap_of(s, made[i].disc);
      for (size_t k = 0; k < i; ++k) {
        if (!caps_apart(ci, cap_of(s, made[k].disc), s.radius, gap)) return std::nullopt;
      }
      const Node& other = nodes_[made[i].b];
      Cap co = cap_of(other.sphere, made[i].disc);
      for (int e : other.edges) {
        Cap existing = cap_of(other.sphere, edges_[e].disc);
        if (!caps_apart(co, existing, other.sphere.radius, gap)) return std::nullopt;
      }
    }
    return made;
  }

  // Interior rooms keep half the wall clearance from the sector's faces, so rooms of
  // neighbouring sectors never come closer than the clearance.
  bool inside_box(const Sphere& s) const {
    double h = face_margin(params_);
    for (int a = 0; a < 3; ++a) {
      if (s.centre[a] < lo_[a] + s.radius + h || s.centre[a] > hi_[a] - s.radius - h) return false;
    }
    return true;
  }

  int add_interior(const Sphere& s, std::vector<Edge> edges) {
    int index = static_cast<int>(nodes_.size()) - gate_count_;
    if (index >= kMaxInteriorRooms) return -1;
    return add(s, RoomId::interior(sector_, index), std::move(edges));
  }

  int add(const Sphere& s, RoomId id, std::vector<Edge> edges) {
    int n = static_cast<int>(nodes_.size());
    nodes_.push_back({s, id, {}});
    parent_.push_back(n);
    for (Edge& e : edges) {
      e.a = n;
      int index = static_cast<int>(edges_.size());
      edges_.push_back(e);
      nodes_[n].edges.push_back(index);
      nodes_[e.b].edges.push_back(index);
      unite(n, e.b);
    }
    cells_.push_back({cell_index(s.centre), cell_coord(s.centre.x, 0), cell_coord(s.centre.y, 1),
                      cell_coord(s.centre.z, 2)});
    seen_.push_back(0);
    // Into every fine cell its bounding box touches.
    int from[3], to[3];
    for (int a = 0; a < 3; ++a) {
      from[a] = fine_coord(s.centre[a] - s.radius, a);
      to[a] = fine_coord(s.centre[a] + s.radius, a);
    }
    for (int x = from[0]; x <= to[0]; ++x)
      for (int y = from[1]; y <= to[1]; ++y)
        for (int z = from[2]; z <= to[2]; ++z)
          fine_[(static_cast<size_t>(x) * fine_dim_ + y) * fine_dim_ + z].push_back({s, n});
    return n;
  }

  int cell_coord(double v, int axis) const {
    int c = static_cast<int>(std::floor((v - lo_[axis]) / cell_)) + 1;
    return std::clamp(c, 0, dim_ - 1);
  }
  int cell_index(Vec3 p) const {
    return (cell_coord(p.x, 0) * dim_ + cell_coord(p.y, 1)) * dim_ + cell_coord(p.z, 2);
  }
  int fine_coord(double v, int axis) const {
    int c = static_cast<int>(std::floor((v - lo_[axis]) / fine_cell_)) + 1;
    return std::clamp(c, 0, fine_dim_ - 1);
  }

  // Spatial index (thesis §3.1.2): the spheres whose gap to s is below `margin` and whose centre
  // lies in the 27 coarse cells around s's (complete for margins up to the one the coarse cell
  // size was chosen for: twice the largest hall). The order is the coarse grid's (cell by cell,
  // then as added), which depends only on what was added: deterministic, and the layout's
  // definition. The candidates come from the fine grid (spheres listed in every fine cell their
  // box touches), so a query reads the few spheres near s rather than, with halls making the
  // coarse cells 70 m wide, most of the sector. Into `out` (cleared first): each caller keeps its
  // own buffer (near_*_ below).
  void nearby(const Sphere& s, double margin, std::vector<int>& out) const {
    out.clear();
    const int cx = cell_coord(s.centre.x, 0), cy = cell_coord(s.centre.y, 1),
              cz = cell_coord(s.centre.z, 2);
    int from[3], to[3];
    for (int a = 0; a < 3; ++a) {
      from[a] = fine_coord(s.centre[a] - s.radius - margin, a);
      to[a] = fine_coord(s.centre[a] + s.radius + margin, a);
    }
    if (++seen_stamp_ == 0) {  // wrapped: forget every stamp
      std::fill(seen_.begin(), seen_.end(), 0);
      seen_stamp_ = 1;
    }
    auto consider = [&](const Cell& c) {
      const Coarse& o = cells_[c.node];
      if (std::abs(o.x - cx) > 1 || std::abs(o.y - cy) > 1 || std::abs(o.z - cz) > 1) return;
      double reach = s.radius + c.sphere.radius + margin;
      if (length_squared(c.sphere.centre - s.centre) < reach * reach) out.push_back(c.node);
    };
    for (int x = from[0]; x <= to[0]; ++x) {
      for (int y = from[1]; y <= to[1]; ++y) {
        for (int z = from[2]; z <= to[2]; ++z) {
          for (const Cell& c : fine_[(static_cast<size_t>(x) * fine_dim_ + y) * fine_dim_ + z]) {
            if (seen_[c.node] == seen_stamp_) continue;
            seen_[c.node] = seen_stamp_;
            consider(c);
          }
        }
      }
    }
    std::sort(out.begin(), out.end(), [this](int a, int b) {
      return cells_[a].index != cells_[b].index ? cells_[a].index < cells_[b].index : a < b;
    });
  }

  int find(int i) {
    while (parent_[i] != i)
      i = parent_[i] = parent_[parent_[i]];
    return i;
  }
  int find_const(int i) const {
    while (parent_[i] != i)
      i = parent_[i];
    return i;
  }
  void unite(int a, int b) {
    a = find(a);
    b = find(b);
    if (a != b) parent_[std::max(a, b)] = std::min(a, b);
  }

  int random_in_component(Rng& rng, int root) {
    std::vector<int> members;
    for (int i = 0; i < static_cast<int>(nodes_.size()); ++i) {
      if (find(i) == root) members.push_back(i);
    }
    return members[rng.below(static_cast<uint32_t>(members.size()))];
  }

  const LayoutParams& params_;
  SectorCoord sector_;
  Vec3 lo_, hi_;
  double cell_ = 1;
  int dim_ = 1;
  int gate_count_ = 0;
  std::vector<Node> nodes_;
  std::vector<Edge> edges_;
  std::vector<int> parent_;
  // The coarse cell of each node's centre (nearby()'s neighbourhood and order), and the fine
  // grid: each fine cell holds the spheres whose box touches it, by value beside their node index
  // (a query reads them in contiguous runs).
  struct Coarse {
    int index, x, y, z;
  };
  std::vector<Coarse> cells_;
  struct Cell {
    Sphere sphere;
    int node;
  };
  static constexpr double kFineCell = 12.0;    // metres
  static constexpr double kMaxFineCells = 16;  // a side, whatever the sector size
  double fine_cell_ = 1;
  int fine_dim_ = 1;
  std::vector<std::vector<Cell>> fine_;
  mutable std::vector<uint32_t> seen_;  // nearby()'s stamps, one a node (grown by add)
  mutable uint32_t seen_stamp_ = 0;
  std::vector<uint32_t> visited_;  // scratch for hops_apart
  // nearby()'s answers, one buffer per caller so that no answer is overwritten while in use.
  mutable std::vector<int> near_shrink_, near_hub_, near_loops_, near_place_;
  uint32_t visit_stamp_ = 0;
};

}  // namespace

std::vector<Room> face_gates(const World& world, SectorCoord lower, int axis) {
  const LayoutParams& p = world.params();
  std::vector<Room> gates;
  SectorCoord upper = neighbour(lower, axis, 1);
  if (!in_range(lower) || !in_range(upper)) return gates;  // the world's edge has no gates
  Rng rng(hash_words(world.seed(), kFaceStream, lower.x, lower.y, lower.z, axis));
  int count = p.gates_min + static_cast<int>(rng.below(p.gates_max - p.gates_min + 1));
  // Gates keep away from the face's edges, so gates of different faces never come near.
  double margin = gate_edge_margin(p);
  for (int tries = 0; static_cast<int>(gates.size()) < count && tries < kTriesPerGate; ++tries) {
    Sphere s;
    s.radius = rng.uniform(p.gate_radius_min, p.gate_radius_max);
    for (int a = 0; a < 3; ++a) {
      double lo = lower[a] * p.sector_size;
      s.centre[a] =
          a == axis ? lo + p.sector_size : rng.uniform(lo + margin, lo + p.sector_size - margin);
    }
    bool clear = std::all_of(gates.begin(), gates.end(), [&](const Room& g) {
      return distance(g.sphere.centre, s.centre) >= g.sphere.radius + s.radius + p.wall_clearance;
    });
    if (clear) {
      int index = static_cast<int>(gates.size());
      gates.push_back({RoomId::gate(lower, axis, index), s, {}});
    }
  }
  return gates;
}

SectorLayout generate_sector(const World& world, SectorCoord sector) {
  assert(in_range(sector));
  std::vector<Room> gates;
  for (int axis = 0; axis < 3; ++axis) {
    for (SectorCoord lower : {neighbour(sector, axis, -1), sector}) {
      std::vector<Room> face = face_gates(world, lower, axis);
      gates.insert(gates.end(), face.begin(), face.end());
    }
  }
  std::sort(gates.begin(), gates.end(), [](const Room& a, const Room& b) { return a.id < b.id; });
  SectorCharacter character = sector_character(world.seed(), world.params(), sector);

  // Whether the hub is a hall comes from a stream of its own, so a sector without one grows the
  // same rooms as if halls did not exist.
  Rng hall_rng(hash_words(world.seed(), kHallStream, sector.x, sector.y, sector.z));
  const bool hall = hall_rng.chance(character.blend.hall_probability);
  const double hall_radius =
      hall ? hall_rng.uniform(character.blend.hall_radius_min, character.blend.hall_radius_max) : 0;

  SectorLayout last;
  for (int attempt = 0; attempt < kMaxAttempts; ++attempt) {
    Rng rng(hash_words(world.seed(), kSectorStream, sector.x, sector.y, sector.z, attempt));
    SectorBuilder builder(world.params(), sector, gates);
    // A big hall leaves the chains little room to reach its wall between floor and spring (with
    // eight attempts at full size, 1 sector in ~600 of seed 7 failed them all): later attempts
    // shrink it, and the last two make the hub a plain big room, as a sector without a hall.
    double hub_hall = hall_radius;
    if (attempt >= kMaxAttempts - 2) {
      hub_hall = 0;
    } else if (attempt >= kMaxAttempts - 5) {
      hub_hall *= 1.0 - 0.15 * (attempt - (kMaxAttempts - 6));
    }
    bool linked = builder.link_gates(rng, character.blend, hub_hall);
    // An attempt whose gates did not link is discarded unless it is the last (returned however it
    // ends): each attempt draws from its own stream, so skipping the growth of one changes
    // nothing else (seed 42's sector 0.0.-1, which needs four attempts, in 3.0 ms instead of 4.0).
    if (!linked && attempt + 1 < kMaxAttempts) continue;
    int link_rooms = builder.interior_count();
    builder.grow(rng, character.blend);
    builder.close_loops(rng, character.blend.loops);
    last = builder.finish(character, attempt + 1, link_rooms);
    if (linked && last.connected) break;
  }
  return last;
}

}  // namespace grotto::cave
