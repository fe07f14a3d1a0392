// A 5x7 bitmap font for the overlay, drawn in this file's companion as readable rows of '#'.
// Upper case, digits and the punctuation a status overlay needs; lower case is drawn as upper case
// and anything else as '?'. Pure data and lookups: no GL.
#pragma once

#include <array>
#include <cstdint>

namespace grotto::render::font {

inline constexpr int kGlyphWidth = 5;
inline constexpr int kGlyphHeight = 7;
// A character cell: the glyph plus one column and one row of spacing.
inline constexpr int kCellWidth = kGlyphWidth + 1;
inline constexpr int kCellHeight = kGlyphHeight + 2;

// Row r (0 = top) of a glyph: bit (kGlyphWidth - 1 - c) set where column c is inked.
using Glyph = std::array<uint8_t, kGlyphHeight>;

// The glyph drawn for `c` (printable ASCII; others give '?').
const Glyph& glyph(char c);
// True when `c` has a glyph of its own (lower case counts: it shares the upper-case glyph).
bool has_glyph(char c);

}  // namespace grotto::render::font
