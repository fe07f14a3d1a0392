// An SVG picture of a region of the layout: a top view (x right, z down) beside a side view
// (x right, y up). Rooms are circles coloured by their sector's character, portals are the discs
// seen edge-on or at a slant, graph edges join room centres, sector boxes are drawn faintly.
#pragma once

#include <string>

#include "common/cave/layout.hpp"

namespace grotto::cave {

struct SvgOptions {
  double panel_size = 640;   // pixels per view
  bool draw_portals = true;  // the portal discs
  bool draw_edges = true;    // lines between the centres of rooms that share a portal
};

std::string region_svg(const World& world, const Region& region, const SvgOptions& options = {});

}  // namespace grotto::cave
