#include "common/cave/svg.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>

namespace grotto::cave {
namespace {

// One colour per character (maze, shafts, caverns), mixed by the sector's weights.
constexpr double kPalette[kCharacterCount][3] = {
    {59, 130, 246},  // blue
    {234, 88, 12},   // orange
    {22, 163, 74},   // green
};

std::string colour(const SectorCharacter& c) {
  double rgb[3] = {0, 0, 0};
  for (int k = 0; k < kCharacterCount; ++k) {
    for (int i = 0; i < 3; ++i)
      rgb[i] += c.weights[k] * kPalette[k][i];
  }
  char buf[16];
  std::snprintf(buf, sizeof buf, "#%02x%02x%02x", static_cast<int>(rgb[0]),
                static_cast<int>(rgb[1]), static_cast<int>(rgb[2]));
  return buf;
}

struct View {
  int u, v;           // world axes shown horizontally and vertically
  bool flip_v;        // y up in the side view
  Vec3 look;          // viewing direction, for portal ellipses
  double ox, oy;      // panel origin in pixels
  double scale;       // pixels per metre
  double u0, v0, v1;  // world range shown
  double px(Vec3 p) const { return ox + (p[u] - u0) * scale; }
  double py(Vec3 p) const { return flip_v ? oy + (v1 - p[v]) * scale : oy + (p[v] - v0) * scale; }
};

void append(std::string& out, const char* fmt, auto... args) {
  char buf[512];
  int n = std::snprintf(buf, sizeof buf, fmt, args...);
  out.append(buf, static_cast<size_t>(std::min(n, static_cast<int>(sizeof buf) - 1)));
}

}  // namespace

std::string region_svg(const World& world, const Region& region, const SvgOptions& options) {
  const double size = world.params().sector_size;
  Vec3 lo{region.lo.x * size, region.lo.y * size, region.lo.z * size};
  Vec3 hi{(region.hi.x + 1) * size, (region.hi.y + 1) * size, (region.hi.z + 1) * size};
  double margin = 16, title = 56;
  double span = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
  double scale = options.panel_size / span;  // one scale for both views, so sizes compare
  View top{0, 2, false, {0, 1, 0}, margin, title, scale, lo.x, lo.z, hi.z};
  double top_w = (hi.x - lo.x) * scale, top_h = (hi.z - lo.z) * scale;
  View side{0, 1, true, {0, 0, 1}, 2 * margin + top_w, title, scale, lo.x, lo.y, hi.y};
  double side_h = (hi.y - lo.y) * scale;
  double width = std::max(3 * margin + 2 * top_w, 720.0);
  double height = title + std::max(top_h, side_h) + margin + 28;
  const double panel_w[2] = {top_w, top_w}, panel_h[2] = {top_h, side_h};

  std::map<SectorCoord, const SectorLayout*> sectors;
  for (const SectorLayout& s : region.sectors)
    sectors[s.sector] = &s;
  auto room_colour = [&](const Room& r) {
    auto it = sectors.find(r.id.sector());
    return it != sectors.end() ? colour(it->second->character) : std::string("#888888");
  };

  std::string out;
  append(out,
         "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"%.0f\" height=\"%.0f\" "
         "viewBox=\"0 0 %.0f %.0f\" font-family=\"sans-serif\">\n",
         width, height, width, height);
  append(out, "<rect width=\"100%%\" height=\"100%%\" fill=\"#0f1115\"/>\n");
  append(out,
         "<text x=\"%.0f\" y=\"24\" fill=\"#e5e7eb\" font-size=\"16\">Grotto layout: seed %llu, "
         "sectors %s to %s, %zu rooms</text>\n",
         margin, static_cast<unsigned long long>(world.seed()), to_string(region.lo).c_str(),
         to_string(region.hi).c_str(), region.rooms.size());
  append(out,
         "<text x=\"%.0f\" y=\"44\" fill=\"#9ca3af\" font-size=\"12\">top view (x right, z down)"
         "</text><text x=\"%.0f\" y=\"44\" fill=\"#9ca3af\" font-size=\"12\">side view (x right, "
         "y up)</text>\n",
         top.ox, side.ox);

  for (int v = 0; v < 2; ++v) {
    const View& w = v == 0 ? top : side;
    append(out,
           "<g><rect x=\"%.1f\" y=\"%.1f\" width=\"%.1f\" height=\"%.1f\" fill=\"#161a21\" "
           "stroke=\"#374151\"/>\n",
           w.ox, w.oy, panel_w[v], panel_h[v]);
    // Sector boxes, tinted by character.
    for (const SectorLayout& s : region.sectors) {
      Vec3 a{s.sector.x * size, s.sector.y * size, s.sector.z * size};
      Vec3 b = a + Vec3{size, size, size};
      double x0 = w.px(a), x1 = w.px(b), y0 = w.py(a), y1 = w.py(b);
      append(out,
             "<rect x=\"%.1f\" y=\"%.1f\" width=\"%.1f\" height=\"%.1f\" fill=\"%s\" "
             "fill-opacity=\"0.10\" stroke=\"#2d3340\" stroke-dasharray=\"4 4\"/>\n",
             std::min(x0, x1), std::min(y0, y1), std::abs(x1 - x0), std::abs(y1 - y0),
             colour(s.character).c_str());
      if (v == 0 && s.sector.y == region.lo.y) {
        // Name the region's character in the corner of each sector of the top view.
        append(out, "<text x=\"%.1f\" y=\"%.1f\" fill=\"%s\" font-size=\"11\">%s %.0f%%</text>\n",
               std::min(x0, x1) + 4, std::min(y0, y1) + 13, colour(s.character).c_str(),
               s.character.blend.name.c_str(), 100 * s.character.weights[s.character.dominant()]);
      }
    }
    // Rooms, largest first so small rooms stay visible.
    std::vector<const Room*> order;
    for (const Room& r : region.rooms)
      order.push_back(&r);
    std::stable_sort(order.begin(), order.end(), [](const Room* a, const Room* b) {
      return a->sphere.radius > b->sphere.radius;
    });
    for (const Room* r : order) {
      append(out,
             "<circle cx=\"%.1f\" cy=\"%.1f\" r=\"%.2f\" fill=\"%s\" fill-opacity=\"0.35\" "
             "stroke=\"%s\" stroke-width=\"%.1f\"><title>%s</title></circle>\n",
             w.px(r->sphere.centre), w.py(r->sphere.centre), r->sphere.radius * w.scale,
             room_colour(*r).c_str(), r->id.is_gate() ? "#f9fafb" : room_colour(*r).c_str(),
             r->id.is_gate() ? 1.5 : 0.8, r->id.to_string().c_str());
    }
    for (const Room& r : region.rooms) {
      for (const Portal& p : r.portals) {
        const Room* other = region.find(p.neighbour);
        if (options.draw_edges && (!other || r.id < p.neighbour)) {
          // An edge to a room outside the region ends at the portal.
          Vec3 end = other ? other->sphere.centre : p.centre;
          append(out,
                 "<line x1=\"%.1f\" y1=\"%.1f\" x2=\"%.1f\" y2=\"%.1f\" stroke=\"#e5e7eb\" "
                 "stroke-opacity=\"0.55\" stroke-width=\"0.8\"/>\n",
                 w.px(r.sphere.centre), w.py(r.sphere.centre), w.px(end), w.py(end));
        }
        if (options.draw_portals && r.id < p.neighbour) {
          // A disc seen along `look` is an ellipse: full radius across the normal, foreshortened
          // by |n . look| along it.
          double nu = p.normal[w.u], nv = w.flip_v ? -p.normal[w.v] : p.normal[w.v];
          double angle = std::atan2(nv, nu) * 180.0 / 3.14159265358979323846;
          double minor = p.radius * std::abs(dot(p.normal, w.look)) * w.scale;
          append(out,
                 "<ellipse cx=\"%.1f\" cy=\"%.1f\" rx=\"%.2f\" ry=\"%.2f\" "
                 "transform=\"rotate(%.1f %.1f %.1f)\" fill=\"none\" stroke=\"#facc15\" "
                 "stroke-opacity=\"0.8\" stroke-width=\"0.8\"/>\n",
                 w.px(p.centre), w.py(p.centre), std::max(minor, 0.6), p.radius * w.scale, angle,
                 w.px(p.centre), w.py(p.centre));
        }
      }
    }
    append(out, "</g>\n");
  }
  // Legend.
  double lx = margin, ly = title + std::max(top_h, side_h) + 20;
  for (int k = 0; k < kCharacterCount; ++k) {
    append(out,
           "<circle cx=\"%.1f\" cy=\"%.1f\" r=\"6\" fill=\"rgb(%.0f,%.0f,%.0f)\"/>"
           "<text x=\"%.1f\" y=\"%.1f\" fill=\"#e5e7eb\" font-size=\"12\">%s</text>\n",
           lx, ly, kPalette[k][0], kPalette[k][1], kPalette[k][2], lx + 10, ly + 4,
           world.params().characters[k].name.c_str());
    lx += 110;
  }
  append(out,
         "<circle cx=\"%.1f\" cy=\"%.1f\" r=\"6\" fill=\"none\" stroke=\"#f9fafb\" "
         "stroke-width=\"1.5\"/><text x=\"%.1f\" y=\"%.1f\" fill=\"#e5e7eb\" "
         "font-size=\"12\">gate room</text>\n",
         lx, ly, lx + 10, ly + 4);
  lx += 110;
  append(out,
         "<line x1=\"%.1f\" y1=\"%.1f\" x2=\"%.1f\" y2=\"%.1f\" stroke=\"#facc15\" "
         "stroke-width=\"2\"/><text x=\"%.1f\" y=\"%.1f\" fill=\"#e5e7eb\" "
         "font-size=\"12\">portal</text>\n",
         lx - 6, ly, lx + 6, ly, lx + 10, ly + 4);
  out += "</svg>\n";
  return out;
}

}  // namespace grotto::cave
