// The overlay: a few lines of status text in the top-left corner over a translucent panel,
// drawn with client/render/font.hpp's 5x7 glyphs as flat quads (no textures). grotto-client
// shows frame time, rooms, latency, bandwidth, the toggles and the connection state with it.
#pragma once

#include <glm/glm.hpp>
#include <string>
#include <vector>

#include "client/render/gl.hpp"
#include "common/core/result.hpp"

namespace grotto::render {

struct OverlayLine {
  std::string text;
  glm::vec4 color{0.86f, 0.9f, 0.95f, 1.0f};
};

// Colours the client uses for its lines.
inline constexpr glm::vec4 kOverlayText{0.86f, 0.9f, 0.95f, 1.0f};
inline constexpr glm::vec4 kOverlayWarning{1.0f, 0.72f, 0.25f, 1.0f};
inline constexpr glm::vec4 kOverlayError{1.0f, 0.35f, 0.3f, 1.0f};

struct OverlayVertex {
  float x, y;        // pixels from the top-left corner of the viewport
  float r, g, b, a;  // straight alpha
};

// Where and how large: `scale` pixels per font dot, the panel's top-left corner at `left`, `top`.
struct OverlayLayout {
  int scale = 2;
  int left = 8;
  int top = 8;
  int padding = 6;    // pixels between the panel's edge and the text
  int max_width = 0;  // pixels the panel may span from `left`; longer lines wrap; 0: no limit
  glm::vec4 panel{0.0f, 0.0f, 0.0f, 0.55f};
};

// Lines wider than `columns` characters broken at spaces (at the limit inside a word longer than
// that), each piece in its line's colour.
std::vector<OverlayLine> wrap_lines(const std::vector<OverlayLine>& lines, size_t columns);

// The triangles of the panel (first six vertices) and of every inked dot of the text, lines
// wrapped to layout.max_width. Pure: the tests check it without a GPU. Nothing (not even the
// panel) for no lines.
std::vector<OverlayVertex> layout_overlay(const std::vector<OverlayLine>& lines,
                                          const OverlayLayout& layout = {});

class Overlay {
 public:
  static Result<Overlay> create();
  // Draws over whatever the bound framebuffer holds (viewport width x height pixels), with depth
  // testing off and alpha blending on; both are restored to off afterwards. Lines wrap at the
  // viewport's right edge (layout.max_width, when 0).
  void draw(const std::vector<OverlayLine>& lines, int width, int height,
            const OverlayLayout& layout = {});

 private:
  Program program_;
  VertexArray vertex_array_;
  Buffer vertices_;
  GLint viewport_ = -1;
};

}  // namespace grotto::render
