#include "tools/report/canvas.h"

#include <cairo-svg.h>
#include <fontconfig/fontconfig.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "core/asan.h"
#include "tools/report/report.h"

namespace mjsysid::report {
namespace {

constexpr char kFontFamily[] = "DejaVu Sans";
constexpr double kMaxCoordinate = 1e6;  // far points pulled in (cairo's fixed point ends at 2^23)

bool Finite(Point p) { return std::isfinite(p.x) && std::isfinite(p.y); }

Point Clamped(Point p) {
  return {std::clamp(p.x, -kMaxCoordinate, kMaxCoordinate),
          std::clamp(p.y, -kMaxCoordinate, kMaxCoordinate)};
}

// `text` with every byte that is not part of a well-formed UTF-8 character replaced by '?'
// (cairo refuses malformed UTF-8 and then draws nothing more)
std::string ValidUtf8(const std::string& text) {
  std::string out;
  for (size_t i = 0; i < text.size();) {
    const auto c = static_cast<unsigned char>(text[i]);
    // the length of the character that c starts, and the smallest code point of that length
    const size_t n = c < 0x80           ? 1
                     : (c >> 5) == 0x6  ? 2
                     : (c >> 4) == 0xE  ? 3
                     : (c >> 3) == 0x1E ? 4
                                        : 0;
    bool ok = n > 0 && i + n <= text.size();
    uint32_t code = n == 1 ? c : n == 2 ? c & 0x1F : n == 3 ? c & 0x0F : c & 0x07;
    for (size_t k = 1; ok && k < n; ++k) {
      const auto cont = static_cast<unsigned char>(text[i + k]);
      ok = (cont & 0xC0) == 0x80;
      code = (code << 6) | (cont & 0x3F);
    }
    // no overlong forms, surrogates or code points beyond U+10FFFF
    static constexpr uint32_t kMin[] = {0, 0, 0x80, 0x800, 0x10000};
    ok = ok && code >= kMin[n] && code <= 0x10FFFF && !(code >= 0xD800 && code <= 0xDFFF);
    if (ok) {
      out.append(text, i, n);
      i += n;
    } else {
      out += '?';
      ++i;
    }
  }
  return out;
}

// throws ReportError when cairo has failed
void Check(cairo_status_t status, const char* what) {
  if (status != CAIRO_STATUS_SUCCESS) {
    throw ReportError(std::string("cannot draw the ") + what +
                      ": cairo: " + cairo_status_to_string(status));
  }
}

// cairo's write callback: appends to a std::string
cairo_status_t Append(void* closure, const unsigned char* data, unsigned int length) {
  static_cast<std::string*>(closure)->append(reinterpret_cast<const char*>(data), length);
  return CAIRO_STATUS_SUCCESS;
}

struct SurfaceDeleter {
  void operator()(cairo_surface_t* s) const { cairo_surface_destroy(s); }
};
struct ContextDeleter {
  void operator()(cairo_t* c) const { cairo_destroy(c); }
};
using Surface = std::unique_ptr<cairo_surface_t, SurfaceDeleter>;
using Context = std::unique_ptr<cairo_t, ContextDeleter>;

// `draw` on a white `surface`, its drawing flushed into the surface
void DrawOn(cairo_surface_t* surface, const Drawing& draw, const char* what) {
  Check(cairo_surface_status(surface), what);
  {
    const Context cr(cairo_create(surface));
    Check(cairo_status(cr.get()), what);
    cairo_set_source_rgb(cr.get(), 1, 1, 1);
    cairo_paint(cr.get());
    Canvas canvas(cr.get());
    draw(canvas);
    Check(cairo_status(cr.get()), what);
  }
  cairo_surface_flush(surface);
  Check(cairo_surface_status(surface), what);
}

// cairo names its ids id="x" and refers to them as xlink:href="#x" and url(#x): each gets `prefix`
std::string PrefixIds(const std::string& svg, const std::string& prefix) {
  static const std::string kMarks[] = {"id=\"", "href=\"#", "url(#"};
  std::string out;
  out.reserve(svg.size() + svg.size() / 8);
  for (size_t i = 0; i < svg.size();) {
    bool marked = false;
    for (const std::string& mark : kMarks) {
      if (svg.compare(i, mark.size(), mark) != 0) continue;
      out += mark + prefix;
      i += mark.size();
      marked = true;
      break;
    }
    if (!marked) out += svg[i++];
  }
  return out;
}

// the svg without the xmlns attributes of its opening tag: HTML puts an inline <svg> and its
// xlink:href attributes in their namespaces itself (and the page then names no URL)
std::string WithoutNamespaces(std::string svg) {
  for (;;) {
    const size_t tag_end = svg.find('>'), at = svg.find(" xmlns");
    if (at >= tag_end) return svg;
    const size_t open = svg.find('"', at), close = svg.find('"', open + 1);
    if (close >= tag_end) return svg;
    svg.erase(at, close + 1 - at);
  }
}

// In sanitizer builds: cairo's font caches and fontconfig's configuration, otherwise kept for the
// life of the process, are released at exit so that LeakSanitizer sees only real leaks.
void ReleaseFontsAtExit() {
#ifdef MJSYSID_ASAN
  static std::once_flag once;
  std::call_once(once, [] {
    std::atexit([] {
      cairo_debug_reset_static_data();
      FcFini();
    });
  });
#endif
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// the canvas

Canvas::Canvas(cairo_t* cr) : cr_(cr) {
  ReleaseFontsAtExit();
  // grey anti-aliasing, light hinting of outlines, unhinted advances (the same layout everywhere)
  cairo_font_options_t* options = cairo_font_options_create();
  cairo_font_options_set_antialias(options, CAIRO_ANTIALIAS_GRAY);
  cairo_font_options_set_hint_style(options, CAIRO_HINT_STYLE_SLIGHT);
  cairo_font_options_set_hint_metrics(options, CAIRO_HINT_METRICS_OFF);
  cairo_set_font_options(cr_, options);
  cairo_font_options_destroy(options);
  cairo_set_font_size(cr_, kFontSize);
  cairo_set_line_join(cr_, CAIRO_LINE_JOIN_ROUND);
  cairo_set_line_cap(cr_, CAIRO_LINE_CAP_BUTT);

  // the height of the capitals: the ink above the baseline of an "H"
  Font(false);
  cairo_text_extents_t e;
  cairo_text_extents(cr_, "H", &e);
  cap_height_ = -e.y_bearing;
}

void Canvas::Font(bool bold) const {
  cairo_select_font_face(cr_, kFontFamily, CAIRO_FONT_SLANT_NORMAL,
                         bold ? CAIRO_FONT_WEIGHT_BOLD : CAIRO_FONT_WEIGHT_NORMAL);
}

void Canvas::Color(Rgb c) { cairo_set_source_rgb(cr_, c.r / 255.0, c.g / 255.0, c.b / 255.0); }

void Canvas::Rect(const Box& b, Rgb fill) {
  if (!Finite({b.x, b.y}) || !Finite({b.w, b.h})) return;
  const Point a = Clamped({b.x, b.y}), z = Clamped({b.right(), b.bottom()});
  cairo_rectangle(cr_, a.x, a.y, z.x - a.x, z.y - a.y);
  Color(fill);
  cairo_fill(cr_);
}

void Canvas::Polyline(const std::vector<Point>& points, Rgb color, double width, double dash) {
  // one sub-path per unbroken piece of two points or more
  cairo_new_path(cr_);
  size_t piece = 0;  // points in the current piece
  for (const Point& p : points) {
    if (!Finite(p)) {
      piece = 0;
      continue;
    }
    const Point q = Clamped(p);
    if (piece++ == 0) {
      cairo_move_to(cr_, q.x, q.y);
    } else {
      cairo_line_to(cr_, q.x, q.y);
    }
  }
  cairo_set_line_width(cr_, width);
  cairo_set_dash(cr_, &dash, dash > 0 ? 1 : 0, 0);
  Color(color);
  cairo_stroke(cr_);
  cairo_set_dash(cr_, nullptr, 0, 0);
}

void Canvas::Disk(Point centre, double radius, Rgb color) {
  if (!Finite(centre) || !(radius > 0)) return;
  const Point c = Clamped(centre);
  cairo_new_path(cr_);
  cairo_arc(cr_, c.x, c.y, radius, 0, 2 * M_PI);
  Color(color);
  cairo_fill(cr_);
}

void Canvas::Text(double x, double y, const std::string& text, Rgb color, Align align, bool bold) {
  if (!Finite({x, y}) || text.empty()) return;
  const std::string utf8 = ValidUtf8(text);
  const double w = TextWidth(utf8, bold);
  const double left = align == Align::kLeft ? x : align == Align::kCenter ? x - w / 2 : x - w;
  Font(bold);
  Color(color);
  cairo_move_to(cr_, left, y + cap_height_);
  cairo_show_text(cr_, utf8.c_str());
  cairo_new_path(cr_);
}

double Canvas::TextWidth(const std::string& text, bool bold) const {
  if (text.empty()) return 0;
  Font(bold);
  cairo_text_extents_t e;
  cairo_text_extents(cr_, ValidUtf8(text).c_str(), &e);
  return e.x_advance;
}

void Canvas::Clip(const Box& b) {
  NoClip();
  const Point a = Clamped({b.x, b.y}), z = Clamped({b.right(), b.bottom()});
  cairo_new_path(cr_);
  cairo_rectangle(cr_, a.x, a.y, z.x - a.x, z.y - a.y);
  cairo_clip(cr_);
}

void Canvas::NoClip() { cairo_reset_clip(cr_); }

// ---------------------------------------------------------------------------------------------
// rendering

std::string RenderPng(int width, int height, const Drawing& draw) {
  const Surface surface(cairo_image_surface_create(CAIRO_FORMAT_RGB24, width, height));
  DrawOn(surface.get(), draw, "PNG");
  std::string png;
  Check(cairo_surface_write_to_png_stream(surface.get(), Append, &png), "PNG");
  return png;
}

std::string RenderSvg(int width, int height, const std::string& id, const Drawing& draw) {
  std::string svg;
  {
    const Surface surface(cairo_svg_surface_create_for_stream(Append, &svg, width, height));
    cairo_svg_surface_set_document_unit(surface.get(), CAIRO_SVG_UNIT_PX);
    DrawOn(surface.get(), draw, "SVG");
    // the surface writes its output when finished
    cairo_surface_finish(surface.get());
    Check(cairo_surface_status(surface.get()), "SVG");
  }
  // the <svg> element alone, its ids unique on the page
  const size_t start = svg.find("<svg");
  if (start == std::string::npos) throw ReportError("cannot draw the SVG: cairo wrote no <svg>");
  return PrefixIds(WithoutNamespaces(svg.substr(start)), id + "-");
}

}  // namespace mjsysid::report
