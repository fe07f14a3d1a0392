// The overlay's font and layout (pure: no GL). grotto_client_test.cpp checks the drawn overlay in
// real screenshots.
#include <gtest/gtest.h>

#include <bit>
#include <set>
#include <string>

#include "client/render/font.hpp"
#include "client/render/overlay.hpp"

namespace grotto::render {
namespace {

int inked_dots(const std::string& text) {
  int n = 0;
  for (char c : text)
    for (uint8_t row : font::glyph(c))
      n += std::popcount(row);
  return n;
}

TEST(Font, draws_every_letter_digit_and_status_punctuation) {
  const std::string needed =
      "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789 .,:;/%-+()[]=_!?'\"<>#*|";
  for (char c : needed)
    EXPECT_TRUE(font::has_glyph(c)) << "'" << c << "'";
  for (char c : needed) {
    if (c == ' ') continue;
    EXPECT_GT(inked_dots(std::string(1, c)), 0) << "'" << c << "'";
  }
  EXPECT_EQ(inked_dots(" "), 0);
}

TEST(Font, glyphs_are_distinct_and_fit_their_cell) {
  std::set<font::Glyph> seen;
  for (char c = 33; c < 127; ++c) {
    if ((c >= 'a' && c <= 'z') || !font::has_glyph(c)) continue;
    const font::Glyph& g = font::glyph(c);
    EXPECT_TRUE(seen.insert(g).second) << "'" << c << "' looks like another character";
    for (uint8_t row : g)
      EXPECT_LT(row, 1u << font::kGlyphWidth) << "'" << c << "'";
  }
}

TEST(Font, lower_case_is_upper_case_and_unknown_characters_are_question_marks) {
  EXPECT_EQ(font::glyph('q'), font::glyph('Q'));
  EXPECT_EQ(font::glyph('\t'), font::glyph('?'));
  EXPECT_EQ(font::glyph('\x80'), font::glyph('?'));
  EXPECT_EQ(font::glyph('~'), font::glyph('?'));
  EXPECT_FALSE(font::has_glyph('~'));
}

TEST(OverlayLayout, a_panel_then_one_quad_per_inked_dot) {
  EXPECT_TRUE(layout_overlay({}).empty());
  const std::vector<OverlayLine> lines{{"FRAME 16.7 MS", kOverlayText},
                                       {"SERVER LOST", kOverlayError}};
  const auto v = layout_overlay(lines);
  ASSERT_EQ(v.size(), 6u * (1 + inked_dots(lines[0].text) + inked_dots(lines[1].text)));
  // The panel comes first, in the panel colour; each line's dots carry the line's colour.
  EXPECT_FLOAT_EQ(v[0].a, OverlayLayout{}.panel.a);
  EXPECT_FLOAT_EQ(v[6].r, kOverlayText.r);
  EXPECT_FLOAT_EQ(v.back().g, kOverlayError.g);
}

TEST(OverlayLayout, text_stays_inside_the_panel_and_scales) {
  const std::vector<OverlayLine> lines{{"ROOMS 12 / 40"}, {"a much longer second line: 123%"}};
  for (int scale : {1, 2, 3}) {
    OverlayLayout layout;
    layout.scale = scale;
    const auto v = layout_overlay(lines, layout);
    const float x0 = v[0].x, y0 = v[0].y, x1 = v[2].x, y1 = v[2].y;
    EXPECT_EQ(x0, static_cast<float>(layout.left));
    EXPECT_EQ(y0, static_cast<float>(layout.top));
    for (size_t i = 6; i < v.size(); ++i) {
      EXPECT_GE(v[i].x, x0 + static_cast<float>(layout.padding));
      EXPECT_LE(v[i].x, x1 - static_cast<float>(layout.padding));
      EXPECT_GE(v[i].y, y0 + static_cast<float>(layout.padding));
      EXPECT_LE(v[i].y, y1 - static_cast<float>(layout.padding));
    }
    // The panel is as wide as the longest line's cells.
    EXPECT_EQ(x1 - x0, static_cast<float>(lines[1].text.size() * font::kCellWidth * scale - scale +
                                          2 * layout.padding));
  }
}

TEST(OverlayLayout, long_lines_wrap_at_spaces_inside_the_width) {
  const std::vector<OverlayLine> lines{
      {"SERVER REFUSED US: world_mismatch this server serves seed 7", kOverlayError}, {"OK"}};
  const auto wrapped = wrap_lines(lines, 20);
  ASSERT_EQ(wrapped.size(), 4u);
  EXPECT_EQ(wrapped[0].text, "SERVER REFUSED US:");
  EXPECT_EQ(wrapped[1].text, "world_mismatch this");
  EXPECT_EQ(wrapped[2].text, "server serves seed 7");
  EXPECT_EQ(wrapped[2].color, kOverlayError) << "pieces keep their line's colour";
  EXPECT_EQ(wrapped[3].text, "OK");
  // A word longer than the width is cut.
  EXPECT_EQ(wrap_lines({{"ABCDEFGHIJ"}}, 4).size(), 3u);

  OverlayLayout layout;
  layout.max_width = 200;
  const auto v = layout_overlay(lines, layout);
  ASSERT_FALSE(v.empty());
  EXPECT_LE(v[2].x - v[0].x, 200.0f) << "the panel fits the width";
  for (size_t i = 6; i < v.size(); ++i)
    EXPECT_LE(v[i].x, static_cast<float>(layout.left + 200));
}

}  // namespace
}  // namespace grotto::render
