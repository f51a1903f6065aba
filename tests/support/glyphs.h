// Real glyph outlines for the curves' tests, read by FreeType (Debian's libfreetype-dev; the
// fonts fonts-dejavu-core's TrueType quadratics and fonts-cantarell's CFF cubics): each
// glyph's contours as closed subpaths (render/kernel/path2.h), in em units, y up.
#pragma once

#include <ft2build.h>
#include FT_FREETYPE_H
#include FT_OUTLINE_H
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "render/kernel/path2.h"

namespace gvd::testing {

inline constexpr const char* kTrueTypeFont = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";
inline constexpr const char* kCffFont = "/usr/share/fonts/opentype/cantarell/Cantarell-Regular.otf";

// The outline of each character of `text` in the font, as FreeType decomposes it.
inline std::vector<std::vector<Subpath>> GlyphOutlines(const char* font, const std::string& text) {
  struct Reader {
    std::vector<Subpath> contours;
    double scale = 1;
    Vec2 At(const FT_Vector* v) const { return {v->x * scale, v->y * scale}; }
    void Add(std::initializer_list<Vec2> points) {
      contours.back().points.insert(contours.back().points.end(), points);
      contours.back().degrees.push_back(static_cast<uint8_t>(points.size()));
    }
  };
  FT_Library library;
  EXPECT_EQ(FT_Init_FreeType(&library), 0);
  FT_Face face;
  EXPECT_EQ(FT_New_Face(library, font, 0, &face), 0) << font;
  FT_Outline_Funcs funcs{};
  funcs.move_to = [](const FT_Vector* to, void* user) {
    auto* r = static_cast<Reader*>(user);
    r->contours.push_back({{r->At(to)}, {}, true});
    return 0;
  };
  funcs.line_to = [](const FT_Vector* to, void* user) {
    auto* r = static_cast<Reader*>(user);
    r->Add({r->At(to)});
    return 0;
  };
  funcs.conic_to = [](const FT_Vector* c, const FT_Vector* to, void* user) {
    auto* r = static_cast<Reader*>(user);
    r->Add({r->At(c), r->At(to)});
    return 0;
  };
  funcs.cubic_to = [](const FT_Vector* c1, const FT_Vector* c2, const FT_Vector* to, void* user) {
    auto* r = static_cast<Reader*>(user);
    r->Add({r->At(c1), r->At(c2), r->At(to)});
    return 0;
  };
  std::vector<std::vector<Subpath>> glyphs;
  for (char ch : text) {
    Reader reader;
    reader.scale = 1.0 / face->units_per_EM;
    const FT_UInt glyph = FT_Get_Char_Index(face, static_cast<unsigned char>(ch));
    EXPECT_NE(glyph, 0u) << ch;
    EXPECT_EQ(FT_Load_Glyph(face, glyph, FT_LOAD_NO_SCALE), 0) << ch;
    EXPECT_EQ(FT_Outline_Decompose(&face->glyph->outline, &funcs, &reader), 0) << ch;
    glyphs.push_back(std::move(reader.contours));
  }
  FT_Done_Face(face);
  FT_Done_FreeType(library);
  return glyphs;
}

// The curves of those outlines (3 or 4 control points each), in order.
inline std::vector<std::vector<Vec2>> GlyphCurves(const char* font, const std::string& text) {
  std::vector<std::vector<Vec2>> curves;
  for (const auto& glyph : GlyphOutlines(font, text)) {
    for (const Subpath& s : glyph) {
      size_t at = 0;
      for (uint8_t degree : s.degrees) {
        if (degree > 1) curves.emplace_back(s.points.begin() + at, s.points.begin() + at + degree + 1);
        at += degree;
      }
    }
  }
  return curves;
}

}  // namespace gvd::testing
