// The report's drawing surface: a few plotting primitives on cairo, rendered to PNG (raster) or to
// an inline SVG element (vector), from the same drawing code.
//
// - Coordinates are pixels (CSS px in the SVG), x to the right, y down, origin top left; a 1 px
//   line is crisp when its centre lies on a half pixel.
// - Colours are 8-bit RGB; the background is white.
// - Text is UTF-8 in fontconfig's match for "DejaVu Sans" at kFontSize px. Glyph metrics are
//   unhinted so a PNG and an SVG of one drawing lay out identically; the SVG holds the glyphs as
//   paths (the page needs no font).
// - Failure: a cairo error (out of memory, a PNG above cairo's 32767 px) throws ReportError.
#pragma once

#include <cairo.h>

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace mjsysid::report {

struct Rgb {
  uint8_t r = 255, g = 255, b = 255;
};

struct Point {
  double x = 0, y = 0;
};

// a rectangle: top left corner, width, height
struct Box {
  double x = 0, y = 0, w = 0, h = 0;
  double right() const { return x + w; }
  double bottom() const { return y + h; }
};

enum class Align { kLeft, kCenter, kRight };

constexpr double kFontSize = 15;  // px

class Canvas {
 public:
  // draws on `cr` (not owned), which outlives the canvas
  explicit Canvas(cairo_t* cr);
  Canvas(const Canvas&) = delete;
  Canvas& operator=(const Canvas&) = delete;

  // a filled rectangle
  void Rect(const Box& b, Rgb fill);

  // a line `width` px wide through the points; a non-finite point breaks it; dash > 0 draws
  // dashes and gaps of that length
  void Polyline(const std::vector<Point>& points, Rgb color, double width, double dash = 0);
  void Line(Point a, Point b, Rgb color, double width, double dash = 0) {
    Polyline({a, b}, color, width, dash);
  }

  // a filled disk (nothing for a non-finite centre)
  void Disk(Point centre, double radius, Rgb color);

  // one line of text whose capitals span [y, y + CapHeight()), aligned at x
  void Text(double x, double y, const std::string& text, Rgb color, Align align, bool bold = false);
  double TextWidth(const std::string& text, bool bold = false) const;
  double CapHeight() const { return cap_height_; }

  // later drawing is clipped to b, until NoClip
  void Clip(const Box& b);
  void NoClip();

 private:
  void Font(bool bold) const;
  void Color(Rgb c);

  cairo_t* const cr_;
  double cap_height_ = 0;
};

// draws a picture on a canvas
using Drawing = std::function<void(Canvas&)>;

// the bytes of a PNG file (8-bit RGB) of `draw` on a white width x height canvas
std::string RenderPng(int width, int height, const Drawing& draw);

// an <svg> element of `draw` on a white width x height canvas, for inline use in an HTML page:
// no XML declaration, every id (glyphs, clip paths) prefixed with `id` + "-" so that several
// such elements can share one page
std::string RenderSvg(int width, int height, const std::string& id, const Drawing& draw);

}  // namespace mjsysid::report
