#include "client/render/overlay.hpp"

#include <algorithm>
#include <cstddef>
#include <string_view>

#include "client/render/font.hpp"
#include "client/render/shaders.hpp"

namespace grotto::render {
namespace {

void append_quad(std::vector<OverlayVertex>& out, float x0, float y0, float x1, float y1,
                 glm::vec4 c) {
  for (auto [x, y] : {std::pair{x0, y0}, {x1, y0}, {x1, y1}, {x0, y0}, {x1, y1}, {x0, y1}})
    out.push_back({x, y, c.r, c.g, c.b, c.a});
}

}  // namespace

std::vector<OverlayLine> wrap_lines(const std::vector<OverlayLine>& lines, size_t columns) {
  columns = std::max<size_t>(columns, 1);
  std::vector<OverlayLine> out;
  for (const OverlayLine& line : lines) {
    std::string_view rest = line.text;
    do {
      size_t cut = rest.size();
      if (rest.size() > columns) {
        cut = rest.rfind(' ', columns);
        if (cut == std::string_view::npos || cut == 0) cut = columns;
      }
      out.push_back({std::string(rest.substr(0, cut)), line.color});
      rest.remove_prefix(cut);
      while (!rest.empty() && rest.front() == ' ')
        rest.remove_prefix(1);
    } while (!rest.empty());
  }
  return out;
}

std::vector<OverlayVertex> layout_overlay(const std::vector<OverlayLine>& unwrapped,
                                          const OverlayLayout& layout) {
  std::vector<OverlayVertex> out;
  if (unwrapped.empty()) return out;
  const int s = std::max(layout.scale, 1);
  const int text_width = layout.max_width - 2 * layout.padding;
  const std::vector<OverlayLine> lines =
      layout.max_width > 0
          ? wrap_lines(unwrapped,
                       static_cast<size_t>(std::max(text_width + s, 0) / (font::kCellWidth * s)))
          : unwrapped;
  size_t columns = 0;
  for (const OverlayLine& line : lines)
    columns = std::max(columns, line.text.size());
  const float width = static_cast<float>(columns * font::kCellWidth * s - s + 2 * layout.padding);
  const float height =
      static_cast<float>(lines.size() * font::kCellHeight * s - 2 * s + 2 * layout.padding);
  const auto left = static_cast<float>(layout.left), top = static_cast<float>(layout.top);
  append_quad(out, left, top, left + width, top + height, layout.panel);

  for (size_t row = 0; row < lines.size(); ++row) {
    const OverlayLine& line = lines[row];
    const int y0 = layout.top + layout.padding + static_cast<int>(row) * font::kCellHeight * s;
    for (size_t column = 0; column < line.text.size(); ++column) {
      const font::Glyph& g = font::glyph(line.text[column]);
      const int x0 = layout.left + layout.padding + static_cast<int>(column) * font::kCellWidth * s;
      for (int r = 0; r < font::kGlyphHeight; ++r) {
        for (int c = 0; c < font::kGlyphWidth; ++c) {
          if ((g[r] >> (font::kGlyphWidth - 1 - c) & 1) == 0) continue;
          const auto x = static_cast<float>(x0 + c * s), y = static_cast<float>(y0 + r * s);
          append_quad(out, x, y, x + static_cast<float>(s), y + static_cast<float>(s), line.color);
        }
      }
    }
  }
  return out;
}

Result<Overlay> Overlay::create() {
  Overlay o;
  auto program = Program::build(text_stages());
  if (!program.ok()) return program.error();
  o.program_ = std::move(program).value();
  o.viewport_ = o.program_.uniform("u_viewport");
  o.vertex_array_ = make_vertex_array();
  o.vertices_ = make_buffer();
  glBindVertexArray(o.vertex_array_.get());
  glBindBuffer(GL_ARRAY_BUFFER, o.vertices_.get());
  glEnableVertexAttribArray(0);
  glVertexAttribPointer(0, 2, GL_FLOAT, GL_FALSE, sizeof(OverlayVertex), nullptr);
  glEnableVertexAttribArray(1);
  glVertexAttribPointer(1, 4, GL_FLOAT, GL_FALSE, sizeof(OverlayVertex),
                        reinterpret_cast<const void*>(offsetof(OverlayVertex, r)));
  glBindVertexArray(0);
  return o;
}

void Overlay::draw(const std::vector<OverlayLine>& lines, int width, int height,
                   const OverlayLayout& layout) {
  if (width <= 0 || height <= 0) return;
  OverlayLayout fitted = layout;
  if (fitted.max_width == 0) fitted.max_width = std::max(width - 2 * fitted.left, 1);
  if (width < 640) fitted.scale = 1;  // small windows: small letters, fewer wrapped lines
  const std::vector<OverlayVertex> vertices = layout_overlay(lines, fitted);
  if (vertices.empty()) return;
  glDisable(GL_DEPTH_TEST);
  glEnable(GL_BLEND);
  glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
  glPolygonMode(GL_FRONT_AND_BACK, GL_FILL);
  program_.use();
  glUniform2f(viewport_, static_cast<float>(width), static_cast<float>(height));
  glBindVertexArray(vertex_array_.get());
  glBindBuffer(GL_ARRAY_BUFFER, vertices_.get());
  glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(vertices.size() * sizeof(OverlayVertex)),
               vertices.data(), GL_STREAM_DRAW);
  glDrawArrays(GL_TRIANGLES, 0, static_cast<GLsizei>(vertices.size()));
  glBindVertexArray(0);
  glDisable(GL_BLEND);
}

}  // namespace grotto::render
