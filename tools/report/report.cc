#include "tools/report/report.h"

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "tools/report/png.h"

namespace mjsysid::report {
namespace {

using io::FitResultFile;
using mjsysid::ParameterEstimate;
using mjsysid::SequenceResult;

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr int kMaxPoints = 2000;  // per plotted line
constexpr int kScale = 2;         // text scale: 12 px per character, 14 px capitals

// palette
constexpr Rgb kWhite{255, 255, 255};
constexpr Rgb kInk{34, 34, 34};
constexpr Rgb kMuted{120, 120, 120};
constexpr Rgb kFrame{160, 160, 160};
constexpr Rgb kGrid{232, 232, 232};
constexpr Rgb kMeasured{165, 165, 165};
constexpr Rgb kBefore{31, 95, 191};
constexpr Rgb kAfter{214, 39, 40};
constexpr Rgb kTruth{30, 150, 60};
constexpr Rgb kUnidentifiable{253, 232, 232};
constexpr Rgb kAlert{198, 40, 40};

// ---------------------------------------------------------------------------------------------
// text

// "%.<digits>g"; inf, -inf, nan spelled out
std::string Num(double v, int digits = 6) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  char buf[40];
  std::snprintf(buf, sizeof(buf), "%.*g", digits, v);
  return buf;
}

// "1e-05" -> "1e-5", "2e+06" -> "2e6"
std::string ShortExponent(std::string s) {
  const size_t e = s.find('e');
  if (e == std::string::npos) return s;
  std::string mant = s.substr(0, e), exp = s.substr(e + 1);
  const bool neg = !exp.empty() && exp[0] == '-';
  if (!exp.empty() && (exp[0] == '+' || exp[0] == '-')) exp.erase(0, 1);
  exp.erase(0, std::min(exp.find_first_not_of('0'), exp.size() - 1));
  return mant + "e" + (neg ? "-" : "") + exp;
}

// text cut to fit `width` pixels on a canvas, "..." marking the cut
std::string Shorten(const std::string& text, double width) {
  if (Image::TextWidth(text, kScale) <= width) return text;
  std::string out = text;
  while (!out.empty() && Image::TextWidth(out + "...", kScale) > width) {
    // drop one utf-8 character
    size_t cut = out.size() - 1;
    while (cut > 0 && (static_cast<unsigned char>(out[cut]) & 0xC0) == 0x80) --cut;
    out.erase(cut);
  }
  return out + "...";
}

std::string HtmlEscape(const std::string& s) {
  std::string out;
  for (const char c : s) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&#39;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

std::string Base64(const std::string& bytes) {
  static constexpr char kAlphabet[] =
      "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  for (size_t i = 0; i < bytes.size(); i += 3) {
    uint32_t v = static_cast<uint8_t>(bytes[i]) << 16;
    if (i + 1 < bytes.size()) v |= static_cast<uint8_t>(bytes[i + 1]) << 8;
    if (i + 2 < bytes.size()) v |= static_cast<uint8_t>(bytes[i + 2]);
    out += kAlphabet[(v >> 18) & 63];
    out += kAlphabet[(v >> 12) & 63];
    out += i + 1 < bytes.size() ? kAlphabet[(v >> 6) & 63] : '=';
    out += i + 2 < bytes.size() ? kAlphabet[v & 63] : '=';
  }
  return out;
}

std::string Hex(Rgb c) {
  char buf[8];
  std::snprintf(buf, sizeof(buf), "#%02x%02x%02x", c.r, c.g, c.b);
  return buf;
}

// ---------------------------------------------------------------------------------------------
// canvas: the same drawing code renders the PNGs and the page's inline SVG

enum class Align { kLeft, kCenter, kRight };

struct Box {
  double x = 0, y = 0, w = 0, h = 0;
  double right() const { return x + w; }
  double bottom() const { return y + h; }
};

class Canvas {
 public:
  virtual ~Canvas() = default;
  virtual void Rect(const Box& b, Rgb fill) = 0;
  // a non-finite point breaks the line; dash > 0: dashes and gaps of that length
  virtual void Polyline(const std::vector<Point>& points, Rgb color, double width, double dash) = 0;
  virtual void Disk(Point centre, double radius, Rgb color) = 0;
  // one line of text whose capitals span [y, y + CapHeight())
  virtual void Text(double x, double y, const std::string& text, Rgb color, Align align) = 0;
  // later drawing is clipped to b, until NoClip
  virtual void Clip(const Box& b) = 0;
  virtual void NoClip() = 0;

  void Line(Point a, Point b, Rgb color, double width, double dash = 0) {
    Polyline({a, b}, color, width, dash);
  }
  static double TextWidth(const std::string& text) { return Image::TextWidth(text, kScale); }
  static double CapHeight() { return Image::kCapHeight * kScale; }
};

class RasterCanvas : public Canvas {
 public:
  RasterCanvas(int width, int height) : image_(width, height) {}
  void Rect(const Box& b, Rgb fill) override {
    image_.FillRect(b.x, b.y, b.right(), b.bottom(), fill);
  }
  void Polyline(const std::vector<Point>& points, Rgb color, double width, double dash) override {
    image_.Polyline(points, color, width, dash);
  }
  void Disk(Point centre, double radius, Rgb color) override {
    image_.Disk(centre.x, centre.y, radius, color);
  }
  void Text(double x, double y, const std::string& text, Rgb color, Align align) override {
    const double w = TextWidth(text);
    const double left = align == Align::kLeft ? x : align == Align::kCenter ? x - w / 2 : x - w;
    image_.Text(static_cast<int>(std::lround(left)), static_cast<int>(std::lround(y)), text, color,
                kScale);
  }
  void Clip(const Box& b) override {
    image_.SetClip(static_cast<int>(std::floor(b.x)), static_cast<int>(std::floor(b.y)),
                   static_cast<int>(std::ceil(b.right())), static_cast<int>(std::ceil(b.bottom())));
  }
  void NoClip() override { image_.ResetClip(); }
  const Image& image() const { return image_; }

 private:
  Image image_;
};

class SvgCanvas : public Canvas {
 public:
  // `id` prefixes the clip path ids: unique per page
  SvgCanvas(int width, int height, std::string id) : id_(std::move(id)) {
    out_ << "<svg viewBox=\"0 0 " << width << " " << height << "\" width=\"" << width
         << "\" height=\"" << height
         << "\" font-family=\"DejaVu Sans Mono, Menlo, Consolas, monospace\" role=\"img\">\n";
  }
  void Rect(const Box& b, Rgb fill) override {
    out_ << "<rect x=\"" << C(b.x) << "\" y=\"" << C(b.y) << "\" width=\"" << C(b.w)
         << "\" height=\"" << C(b.h) << "\" fill=\"" << Hex(fill) << "\"/>\n";
  }
  void Polyline(const std::vector<Point>& points, Rgb color, double width, double dash) override {
    // one element per unbroken piece
    size_t i = 0;
    while (i < points.size()) {
      std::string coords;
      size_t n = 0;
      for (; i < points.size() && std::isfinite(points[i].x) && std::isfinite(points[i].y); ++i) {
        coords += (n++ ? " " : "") + C(points[i].x) + "," + C(points[i].y);
      }
      if (n >= 2) {
        out_ << "<polyline fill=\"none\" stroke=\"" << Hex(color) << "\" stroke-width=\""
             << C(width) << "\" stroke-linejoin=\"round\"";
        if (dash > 0) out_ << " stroke-dasharray=\"" << C(dash) << " " << C(dash) << "\"";
        out_ << " points=\"" << coords << "\"/>\n";
      }
      ++i;
    }
  }
  void Disk(Point centre, double radius, Rgb color) override {
    if (!std::isfinite(centre.x) || !std::isfinite(centre.y)) return;
    out_ << "<circle cx=\"" << C(centre.x) << "\" cy=\"" << C(centre.y) << "\" r=\"" << C(radius)
         << "\" fill=\"" << Hex(color) << "\"/>\n";
  }
  void Text(double x, double y, const std::string& text, Rgb color, Align align) override {
    // monospace at 10 px per scale unit: 0.6 em advance = the bitmap font's 6 px
    const char* anchor = align == Align::kLeft     ? "start"
                         : align == Align::kCenter ? "middle"
                                                   : "end";
    out_ << "<text x=\"" << C(x) << "\" y=\"" << C(y + CapHeight()) << "\" font-size=\""
         << 10 * kScale << "\" text-anchor=\"" << anchor << "\" fill=\"" << Hex(color) << "\">"
         << HtmlEscape(text) << "</text>\n";
  }
  void Clip(const Box& b) override {
    NoClip();
    const std::string id = id_ + "-clip" + std::to_string(clips_++);
    out_ << "<clipPath id=\"" << id << "\"><rect x=\"" << C(b.x) << "\" y=\"" << C(b.y)
         << "\" width=\"" << C(b.w) << "\" height=\"" << C(b.h) << "\"/></clipPath>\n"
         << "<g clip-path=\"url(#" << id << ")\">\n";
    clipped_ = true;
  }
  void NoClip() override {
    if (clipped_) out_ << "</g>\n";
    clipped_ = false;
  }
  std::string Finish() {
    NoClip();
    out_ << "</svg>\n";
    return out_.str();
  }

 private:
  // a coordinate: one decimal, far values pulled in
  static std::string C(double v) {
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%.1f", std::clamp(v, -1e5, 1e5));
    return buf;
  }
  std::ostringstream out_;
  std::string id_;
  int clips_ = 0;
  bool clipped_ = false;
};

// ---------------------------------------------------------------------------------------------
// axes

// the span of the finite values added
struct Range {
  double lo = kInf, hi = -kInf;
  void Add(double v) {
    if (!std::isfinite(v)) return;
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  bool empty() const { return !(lo <= hi); }
};

struct Axis {
  double lo = 0, hi = 1;
  bool log = false;
  // the pixel coordinate of v, p0 at lo and p1 at hi; NaN for v <= 0 on a log axis
  double Map(double v, double p0, double p1) const {
    double a = lo, b = hi, x = v;
    if (log) {
      if (!(v > 0)) return std::numeric_limits<double>::quiet_NaN();
      a = std::log10(lo);
      b = std::log10(hi);
      x = std::log10(v);
    }
    const double p = p0 + (x - a) / (b - a) * (p1 - p0);
    return std::isnan(p) ? p : std::clamp(p, -1e6, 1e6);
  }
};

// a linear axis over r with `pad` of its span added on both sides
Axis LinearAxis(const Range& r, double pad) {
  if (r.empty()) return Axis{0, 1, false};
  double lo = r.lo, hi = r.hi;
  if (hi - lo <= 1e-12 * std::max(std::abs(lo), std::abs(hi))) {
    const double half = lo == 0 ? 1 : 0.05 * std::abs(lo);
    return Axis{lo - half, hi + half, false};
  }
  const double span = hi - lo;
  return Axis{lo - pad * span, hi + pad * span, false};
}

// a log axis over r (positive values) from one decade boundary to the next
Axis LogAxis(const Range& r) {
  if (r.empty() || r.lo <= 0) return Axis{0.1, 10, true};
  double lo = std::pow(10.0, std::floor(std::log10(r.lo)));
  double hi = std::pow(10.0, std::ceil(std::log10(r.hi)));
  if (!(hi > lo)) hi = lo * 10;
  return Axis{lo, hi, true};
}

// 1, 2, 5 x 10^k steps, about `target` ticks inside the axis
std::vector<double> LinearTicks(const Axis& a, int target, double* step) {
  const double raw = (a.hi - a.lo) / target;
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  *step = mag * 10;
  for (const double m : {1.0, 2.0, 5.0}) {
    if (m * mag >= raw) {
      *step = m * mag;
      break;
    }
  }
  std::vector<double> ticks;
  for (double k = std::ceil(a.lo / *step - 1e-9); k * *step <= a.hi + 1e-9 * *step; k += 1) {
    const double v = k * *step;
    ticks.push_back(std::abs(v) < 1e-9 * *step ? 0.0 : v);
    if (ticks.size() > 50) break;
  }
  return ticks;
}

// decades (every k-th when many), with 2 and 5 between when there are few
std::vector<double> LogTicks(const Axis& a) {
  const int d0 = static_cast<int>(std::lround(std::log10(a.lo)));
  const int d1 = static_cast<int>(std::lround(std::log10(a.hi)));
  const int every = std::max(1, (d1 - d0 + 7) / 8);
  std::vector<double> ticks;
  for (int d = d0; d <= d1; ++d) {
    const double decade = std::pow(10.0, d);
    if ((d - d0) % every == 0) ticks.push_back(decade);
    if (d1 - d0 <= 2 && d < d1) {
      ticks.push_back(2 * decade);
      ticks.push_back(5 * decade);
    }
  }
  std::sort(ticks.begin(), ticks.end());
  return ticks;
}

std::string TickLabel(double v, double step, bool log) {
  if (v == 0) return "0";
  char buf[40];
  const double av = std::abs(v);
  if (log || av >= 1e5 || av < 1e-3) {
    std::snprintf(buf, sizeof(buf), "%.3g", v);
    return ShortExponent(buf);
  }
  const int decimals = std::clamp(static_cast<int>(-std::floor(std::log10(step) + 1e-9)), 0, 10);
  std::snprintf(buf, sizeof(buf), "%.*f", decimals, v);
  return buf;
}

// a panel's plotting area and axes
struct Panel {
  Box plot;
  Axis x, y;
  Point Map(double xv, double yv) const {
    return {x.Map(xv, plot.x, plot.right()), y.Map(yv, plot.bottom(), plot.y)};
  }
};

// the title, background, grid, frame and tick labels of a panel in `outer`
Panel DrawPanel(Canvas& c, const Box& outer, const std::string& title, Rgb title_color,
                const Axis& x, const Axis& y, const std::string& xlabel, Rgb background,
                double min_left = 0) {
  const double cap = Canvas::CapHeight();

  // ticks and their labels first: the widest y label sets the left margin
  double xstep = 1, ystep = 1;
  const std::vector<double> xticks = x.log ? LogTicks(x) : LinearTicks(x, 6, &xstep);
  const std::vector<double> yticks = y.log ? LogTicks(y) : LinearTicks(y, 5, &ystep);
  std::vector<std::string> ylabels;
  double ylabel_width = 0;
  for (const double v : yticks) {
    ylabels.push_back(TickLabel(v, ystep, y.log));
    ylabel_width = std::max(ylabel_width, Canvas::TextWidth(ylabels.back()));
  }
  Panel p;
  p.x = x;
  p.y = y;
  p.plot.x = std::round(outer.x + std::max(min_left, 12 + ylabel_width + 8));
  p.plot.y = std::round(outer.y + 10 + cap + 10);
  p.plot.w = std::round(outer.right() - 16 - p.plot.x);
  p.plot.h = std::round(outer.bottom() - 10 - cap - 8 - (xlabel.empty() ? 0 : cap + 10) - p.plot.y);

  // title, plot background, grid, frame
  c.Text(p.plot.x, outer.y + 10, Shorten(title, outer.right() - 8 - p.plot.x), title_color,
         Align::kLeft);
  c.Rect(p.plot, background);
  for (const double v : xticks) {
    const double px = std::round(p.Map(v, 0).x) + 0.5;
    c.Line({px, p.plot.y}, {px, p.plot.bottom()}, kGrid, 1);
    c.Text(px, p.plot.bottom() + 8, TickLabel(v, xstep, x.log), kInk, Align::kCenter);
  }
  for (size_t i = 0; i < yticks.size(); ++i) {
    const double py = std::round(p.Map(x.lo, yticks[i]).y) + 0.5;
    c.Line({p.plot.x, py}, {p.plot.right(), py}, kGrid, 1);
    c.Text(p.plot.x - 8, py - cap / 2, ylabels[i], kInk, Align::kRight);
  }
  const double l = p.plot.x - 0.5, t = p.plot.y - 0.5, r = p.plot.right() + 0.5,
               b = p.plot.bottom() + 0.5;
  c.Polyline({{l, t}, {r, t}, {r, b}, {l, b}, {l, t}}, kFrame, 1, 0);
  if (!xlabel.empty()) {
    c.Text(p.plot.x + p.plot.w / 2, p.plot.bottom() + 8 + cap + 10, xlabel, kMuted, Align::kCenter);
  }
  return p;
}

// a line (and markers) of data in a panel, clipped to its plotting area
void DrawSeries(Canvas& c, const Panel& p, const std::vector<double>& xs,
                const std::vector<double>& ys, Rgb color, double width, double dash,
                double marker = 0) {
  std::vector<Point> points;
  for (size_t i = 0; i < xs.size() && i < ys.size(); ++i) points.push_back(p.Map(xs[i], ys[i]));
  c.Clip(p.plot);
  if (width > 0) c.Polyline(points, color, width, dash);
  if (marker > 0) {
    for (const Point& pt : points) c.Disk(pt, marker, color);
  }
  c.NoClip();
}

struct LegendItem {
  std::string label;
  Rgb color;
  double dash = 0;
  bool marker = false;
};

// items side by side from (x, y): a line sample, then the label
void DrawLegend(Canvas& c, double x, double y, const std::vector<LegendItem>& items) {
  const double mid = y + Canvas::CapHeight() / 2;
  for (const LegendItem& item : items) {
    c.Line({x, mid}, {x + 30, mid}, item.color, 2.5, item.dash);
    if (item.marker) c.Disk({x + 15, mid}, 4, item.color);
    c.Text(x + 38, y, item.label, kInk, Align::kLeft);
    x += 38 + Canvas::TextWidth(item.label) + 28;
  }
}

// indices of the samples to plot: all up to kMaxPoints, else the first and last sample and the
// minimum and maximum of each of kMaxPoints / 2 buckets, in order (peaks survive)
std::vector<Eigen::Index> Decimate(const Eigen::Ref<const Eigen::VectorXd>& y) {
  const Eigen::Index n = y.size();
  std::vector<Eigen::Index> out;
  if (n <= kMaxPoints) {
    for (Eigen::Index i = 0; i < n; ++i) out.push_back(i);
    return out;
  }
  const Eigen::Index buckets = kMaxPoints / 2 - 1;
  out.push_back(0);
  for (Eigen::Index b = 0; b < buckets; ++b) {
    const Eigen::Index lo = 1 + b * (n - 2) / buckets, hi = 1 + (b + 1) * (n - 2) / buckets;
    Eigen::Index imin = lo, imax = lo;
    for (Eigen::Index i = lo; i < hi; ++i) {
      if (y[i] < y[imin]) imin = i;
      if (y[i] > y[imax]) imax = i;
    }
    out.push_back(std::min(imin, imax));
    if (imax != imin) out.push_back(std::max(imin, imax));
  }
  out.push_back(n - 1);
  return out;
}

// ---------------------------------------------------------------------------------------------
// the plots

// panels side by side line up while their y labels fit in 6 characters
constexpr double kLeftMargin = 12 + 6 * Image::kCellWidth * kScale + 8;
constexpr int kCostWidth = 900, kCostHeight = 440;
constexpr int kParamWidth = 400, kParamHeight = 260, kLegendHeight = 44;
constexpr int kSeqWidth = 1200, kSeqPanelHeight = 230, kSeqHeaderHeight = 76;

void DrawCost(Canvas& c, const FitResultFile& r) {
  // the trace, or the first and last cost without one
  std::vector<double> xs, ys, bad_x, bad_y;
  for (const IterationInfo& e : r.trace) {
    xs.push_back(e.iteration);
    ys.push_back(e.cost);
    if (!e.successful) {
      bad_x.push_back(e.iteration);
      bad_y.push_back(e.cost);
    }
  }
  if (xs.empty()) {
    xs = {0.0, static_cast<double>(r.iterations)};
    ys = {r.initial_cost, r.final_cost};
  }
  Range xr, yr;
  bool positive = true;
  for (size_t i = 0; i < xs.size(); ++i) {
    xr.Add(xs[i]);
    yr.Add(ys[i]);
    if (std::isfinite(ys[i]) && ys[i] <= 0) positive = false;
  }
  Axis xa = LinearAxis(xr, 0.03);
  if (xa.hi - xa.lo < 1) xa = Axis{xr.empty() ? 0 : xr.lo - 0.5, (xr.empty() ? 0 : xr.lo) + 0.5};
  const Axis ya = positive ? LogAxis(yr) : LinearAxis(yr, 0.05);
  const std::string title = "cost vs iteration" + std::string(positive ? " (log scale)" : "") +
                            ": " + Num(r.initial_cost, 4) + " -> " + Num(r.final_cost, 4);
  const Panel p =
      DrawPanel(c, Box{0, 0, kCostWidth, kCostHeight}, title, kInk, xa, ya, "iteration", kWhite);
  DrawSeries(c, p, xs, ys, kBefore, 2, 0, 3.5);
  if (!bad_x.empty()) {
    DrawSeries(c, p, bad_x, bad_y, kAlert, 0, 0, 4.5);
    DrawLegend(c, p.plot.right() - 230, p.plot.y + 10, {{"step rejected", kAlert, 0, true}});
  }
}

int ParamColumns(const FitResultFile& r) {
  return std::clamp(static_cast<int>(r.parameters.size()), 1, 3);
}
int ParamRows(const FitResultFile& r) {
  const int n = std::max(1, static_cast<int>(r.parameters.size()));
  return (n + ParamColumns(r) - 1) / ParamColumns(r);
}

// one parameter: its values over the iterations, the final value with its interval, the truth
void DrawParameter(Canvas& c, const FitResultFile& r, size_t j, const Box& box) {
  const ParameterEstimate& par = r.parameters[j];
  std::vector<double> xs, ys;
  for (const IterationInfo& e : r.trace) {
    if (e.parameters.size() != static_cast<Eigen::Index>(r.parameters.size())) continue;
    xs.push_back(e.iteration);
    ys.push_back(e.parameters[j]);
  }
  if (xs.empty()) {
    xs = {0.0, static_cast<double>(r.iterations)};
    ys = {par.initial, par.value};
  }

  // the final value's bar stands right of the trajectory
  Range xr, yr;
  for (size_t i = 0; i < xs.size(); ++i) {
    xr.Add(xs[i]);
    yr.Add(ys[i]);
  }
  const double span = xr.empty() ? 1 : std::max(1.0, xr.hi - xr.lo);
  const double bar_x = (xr.empty() ? 0 : xr.hi) + 0.12 * span;
  xr.Add(bar_x);
  for (const double v : {par.value, par.ci95_low, par.ci95_high}) yr.Add(v);
  if (par.truth) yr.Add(*par.truth);
  const Axis xa = LinearAxis(xr, 0.04);
  const Axis ya = LinearAxis(yr, 0.08);

  // title: the name and its flags
  std::string title = par.name;
  if (par.at_lower) title += " [lower bound]";
  if (par.at_upper) title += " [upper bound]";
  if (!par.identifiable) title += " (unidentifiable)";
  const Panel p = DrawPanel(c, box, title, par.identifiable ? kInk : kAlert, xa, ya, "iteration",
                            par.identifiable ? kWhite : kUnidentifiable, kLeftMargin);

  // truth, trajectory, final value with its interval (infinite ends run off the panel)
  if (par.truth) {
    DrawSeries(c, p, {xa.lo, xa.hi}, {*par.truth, *par.truth}, kTruth, 2, 7);
  }
  DrawSeries(c, p, xs, ys, kBefore, 1.8, 0, xs.size() <= 60 ? 2.5 : 0);
  const double lo = std::isfinite(par.ci95_low) ? par.ci95_low : -1e300;
  const double hi = std::isfinite(par.ci95_high) ? par.ci95_high : 1e300;
  c.Clip(p.plot);
  const Point top = p.Map(bar_x, hi), bottom = p.Map(bar_x, lo);
  c.Line(top, bottom, kAfter, 2);
  if (std::isfinite(par.ci95_high)) c.Line({top.x - 6, top.y}, {top.x + 6, top.y}, kAfter, 2);
  if (std::isfinite(par.ci95_low)) {
    c.Line({bottom.x - 6, bottom.y}, {bottom.x + 6, bottom.y}, kAfter, 2);
  }
  c.Disk(p.Map(bar_x, par.value), 4.5, kAfter);
  c.NoClip();
}

void DrawParameters(Canvas& c, const FitResultFile& r) {
  DrawLegend(c, 14, 14,
             {{"iterations", kBefore, 0, true},
              {"final, 95% CI", kAfter, 0, true},
              {"truth", kTruth, 7, false}});
  if (r.parameters.empty()) {
    c.Text(14, kLegendHeight + 20, "no parameters", kMuted, Align::kLeft);
    return;
  }
  const int cols = ParamColumns(r);
  for (size_t j = 0; j < r.parameters.size(); ++j) {
    const Box box{static_cast<double>((j % cols) * kParamWidth),
                  static_cast<double>(kLegendHeight + (j / cols) * kParamHeight), kParamWidth,
                  kParamHeight};
    DrawParameter(c, r, j, box);
  }
}

// the column labels of a sequence: the sensor name, with [i] for multi-column sensors
std::vector<std::string> ColumnLabels(const SequenceResult& s) {
  std::vector<std::string> out;
  for (size_t i = 0; i < s.sensor_names.size() && i < s.sensor_dims.size(); ++i) {
    for (int k = 0; k < s.sensor_dims[i]; ++k) {
      out.push_back(s.sensor_dims[i] == 1 ? s.sensor_names[i]
                                          : s.sensor_names[i] + "[" + std::to_string(k) + "]");
    }
  }
  while (static_cast<Eigen::Index>(out.size()) < s.measured.cols()) {
    out.push_back("column " + std::to_string(out.size()));
  }
  return out;
}

int SeqColumns(const SequenceResult& s) { return s.measured.cols() > 4 ? 2 : 1; }
int SeqRows(const SequenceResult& s) {
  const auto n = static_cast<int>(std::max<Eigen::Index>(1, s.measured.cols()));
  return (n + SeqColumns(s) - 1) / SeqColumns(s);
}

void DrawSequence(Canvas& c, const SequenceResult& s) {
  // header: what this is, and the legend
  const Eigen::Index samples = s.time.size();
  std::string header = "sequence " + s.name;
  if (!s.model.empty()) header += " (model " + s.model + ")";
  header += ", " + std::to_string(samples) + " samples";
  if (samples > 0)
    header += ", t = " + Num(s.time[0], 4) + " .. " + Num(s.time[samples - 1], 4) + " s";
  c.Text(14, 14, Shorten(header, kSeqWidth - 28), kInk, Align::kLeft);
  DrawLegend(c, 14, 14 + Canvas::CapHeight() + 16,
             {{"measured", kMeasured, 0, false},
              {"simulated, initial parameters", kBefore, 6, false},
              {"simulated, fitted parameters", kAfter, 0, false}});

  const std::vector<std::string> labels = ColumnLabels(s);
  const int cols = SeqColumns(s), rows = SeqRows(s);
  const double width = static_cast<double>(kSeqWidth) / cols;
  Range tr;
  for (Eigen::Index k = 0; k < samples; ++k) tr.Add(s.time[k]);
  const Axis ta = LinearAxis(tr, 0);
  for (Eigen::Index j = 0; j < s.measured.cols(); ++j) {
    const int row = static_cast<int>(j / cols), col = static_cast<int>(j % cols);
    const Box box{col * width, static_cast<double>(kSeqHeaderHeight + row * kSeqPanelHeight), width,
                  kSeqPanelHeight};

    // y range: measured and fitted; the initial simulation only up to half a span beyond
    Range inner, before;
    for (Eigen::Index k = 0; k < samples; ++k) {
      inner.Add(s.measured(k, j));
      inner.Add(s.simulated_final(k, j));
      before.Add(s.simulated_initial(k, j));
    }
    Range yr = inner;
    if (!before.empty()) {
      const double half = inner.empty() ? 0 : 0.5 * std::max(inner.hi - inner.lo, 1e-12);
      yr.Add(inner.empty() ? before.lo : std::max(before.lo, inner.lo - half));
      yr.Add(inner.empty() ? before.hi : std::min(before.hi, inner.hi + half));
    }
    const Panel p =
        DrawPanel(c, box, labels[static_cast<size_t>(j)], kInk, ta, LinearAxis(yr, 0.06),
                  row == rows - 1 ? "time (s)" : "", kWhite, kLeftMargin);

    // each line decimated on its own
    const std::pair<const RowMatrix*, Rgb> lines[] = {
        {&s.measured, kMeasured}, {&s.simulated_initial, kBefore}, {&s.simulated_final, kAfter}};
    for (const auto& [m, color] : lines) {
      const Eigen::VectorXd y = m->col(j);
      std::vector<double> xs, ys;
      for (const Eigen::Index k : Decimate(y)) {
        xs.push_back(s.time[k]);
        ys.push_back(y[k]);
      }
      const bool measured = m == &s.measured;
      // measured: a wide light band under the simulations
      DrawSeries(c, p, xs, ys, color, measured ? 3 : 1.6, m == &s.simulated_initial ? 6 : 0,
                 samples == 1 ? 3 : 0);
    }
  }
}

// ---------------------------------------------------------------------------------------------
// the page

// the css class of a status badge
std::string StatusClass(const std::string& status) {
  std::string s = status;
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char ch) { return std::tolower(ch); });
  if (s.find("fail") != std::string::npos || s.find("error") != std::string::npos ||
      s.find("diverg") != std::string::npos) {
    return "bad";
  }
  if (s == "converged" || s == "success" || s == "succeeded" || s == "ok" || s == "done") {
    return "ok";
  }
  return "warn";
}

// a number for the page: 6 digits, infinity as the sign
std::string HtmlNum(double v, int digits = 6) {
  if (std::isinf(v)) return v > 0 ? "\xE2\x88\x9E" : "\xE2\x88\x92\xE2\x88\x9E";
  return HtmlEscape(Num(v, digits));
}

constexpr char kCss[] = R"css(
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,Helvetica,Arial,sans-serif;color:#222;
  max-width:1240px;margin:24px auto;padding:0 16px;line-height:1.4}
h1{font-size:26px;margin:0 0 6px}
h2{font-size:20px;margin:32px 0 10px;padding-bottom:4px;border-bottom:1px solid #ddd}
h3{font-size:16px;margin:20px 0 6px}
.badge{display:inline-block;padding:1px 10px;border-radius:10px;color:#fff;font-weight:600}
.ok{background:#2e7d32}.warn{background:#ef6c00}.bad{background:#c62828}
.muted{color:#777}
table{border-collapse:collapse;font-size:14px;margin:4px 0}
th,td{padding:4px 10px;border-bottom:1px solid #eee;text-align:left;vertical-align:top}
th{background:#f6f6f6}
td.n{text-align:right;font-family:ui-monospace,Menlo,Consolas,monospace;white-space:nowrap}
table.facts td:first-child{color:#666}
tr.unid td{background:#fde8e8}
.flag{display:inline-block;padding:0 6px;margin:0 4px 2px 0;border-radius:4px;font-size:12px;
  background:#e8e8e8}
.flag.unid{background:#c62828;color:#fff}
ul.warnings li{color:#8a4b00}
svg,img{max-width:100%;height:auto;border:1px solid #eee;background:#fff}
)css";

// the parameter table, with the unidentifiable combinations below it
void ParameterSection(std::ostringstream& h, const FitResultFile& r) {
  h << "<h2>Parameters</h2>\n";
  if (r.parameters.empty()) {
    h << "<p class=\"muted\">no parameters</p>\n";
  } else {
    h << "<table class=\"params\">\n<tr><th>parameter</th><th>initial</th><th>value</th>"
         "<th>std</th><th>rel. std</th><th>95% CI</th><th>truth</th><th>truth in CI</th>"
         "<th>flags</th></tr>\n";
    for (const ParameterEstimate& p : r.parameters) {
      h << "<tr" << (p.identifiable ? "" : " class=\"unid\"") << "><td>" << HtmlEscape(p.name)
        << "</td><td class=\"n\">" << HtmlNum(p.initial) << "</td><td class=\"n\"><b>"
        << HtmlNum(p.value) << "</b></td><td class=\"n\">" << HtmlNum(p.std_error, 3)
        << "</td><td class=\"n\">"
        << (std::isinf(p.std_error) ? HtmlNum(p.std_error)
            : p.value != 0          ? HtmlNum(100 * p.std_error / std::abs(p.value), 3) + " %"
                                    : "&ndash;")
        << "</td><td class=\"n\">[" << HtmlNum(p.ci95_low) << ", " << HtmlNum(p.ci95_high)
        << "]</td><td class=\"n\">" << (p.truth ? HtmlNum(*p.truth) : "&ndash;") << "</td><td>";
      if (p.truth) h << (*p.truth >= p.ci95_low && *p.truth <= p.ci95_high ? "yes" : "<b>no</b>");
      h << "</td><td>";
      if (p.at_lower) h << "<span class=\"flag\">at lower bound</span>";
      if (p.at_upper) h << "<span class=\"flag\">at upper bound</span>";
      if (!p.identifiable) h << "<span class=\"flag unid\">unidentifiable</span>";
      h << "</td></tr>\n";
    }
    h << "</table>\n";
  }
  h << "<h3>Unidentifiable combinations</h3>\n";
  if (r.uncertainty.unidentifiable.empty()) {
    h << "<p class=\"muted\">none: the data determine every parameter</p>\n";
  } else {
    h << "<ul>\n";
    for (const std::string& u : r.uncertainty.unidentifiable)
      h << "<li>" << HtmlEscape(u) << "</li>\n";
    h << "</ul>\n";
  }
}

std::string Html(const FitResultFile& r, const std::vector<std::string>& sequence_pngs) {
  std::ostringstream h;
  const std::string name = r.name.empty() ? "(unnamed)" : r.name;
  h << "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
    << "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
    << "<title>mjsysid report: " << HtmlEscape(name) << "</title>\n<style>" << kCss
    << "</style>\n</head>\n<body>\n";

  // header
  h << "<h1>" << HtmlEscape(name) << "</h1>\n<p><span class=\"badge " << StatusClass(r.status)
    << "\">" << HtmlEscape(r.status.empty() ? "unknown" : r.status) << "</span> "
    << HtmlEscape(r.termination) << "</p>\n";

  // facts
  const double ratio = r.initial_cost != 0 ? r.final_cost / r.initial_cost : kInf;
  const std::pair<std::string, std::string> facts[] = {
      {"experiment", HtmlEscape(r.experiment)},
      {"created", HtmlEscape(r.created)},
      {"iterations", std::to_string(r.iterations)},
      {"initial cost", HtmlNum(r.initial_cost)},
      {"final cost", HtmlNum(r.final_cost) + " <span class=\"muted\">(" + HtmlNum(ratio, 3) +
                         " of the initial)</span>"},
      {"residual variance", HtmlNum(r.uncertainty.residual_variance)},
      {"residuals", std::to_string(r.num_residuals)},
      {"wall time", HtmlNum(r.seconds, 4) + " s"},
      {"jacobian", HtmlEscape(r.jacobian_mode)},
      {"versions",
       "mjsysid " + HtmlEscape(r.mjsysid_version) + ", MuJoCo " + HtmlEscape(r.mujoco_version)}};
  h << "<table class=\"facts\">\n";
  for (const auto& [key, value] : facts)
    h << "<tr><td>" << key << "</td><td>" << value << "</td></tr>\n";
  for (const auto& [model, file] : r.identified_models) {
    h << "<tr><td>identified model</td><td>" << HtmlEscape(model) << ": " << HtmlEscape(file)
      << "</td></tr>\n";
  }
  h << "</table>\n";

  // solver settings
  h << "<h2>Solver settings</h2>\n";
  if (r.solver.empty()) {
    h << "<p class=\"muted\">none recorded</p>\n";
  } else {
    h << "<table class=\"facts\">\n";
    for (const auto& [key, value] : r.solver) {
      h << "<tr><td>" << HtmlEscape(key) << "</td><td>" << HtmlEscape(value) << "</td></tr>\n";
    }
    h << "</table>\n";
  }

  ParameterSection(h, r);

  // warnings
  h << "<h2>Warnings</h2>\n";
  if (r.warnings.empty()) {
    h << "<p class=\"muted\">none</p>\n";
  } else {
    h << "<ul class=\"warnings\">\n";
    for (const std::string& w : r.warnings) h << "<li>" << HtmlEscape(w) << "</li>\n";
    h << "</ul>\n";
  }

  // plots: cost and parameters as svg, sequences as png
  h << "<h2>Cost</h2>\n";
  SvgCanvas cost(kCostWidth, kCostHeight, "cost");
  DrawCost(cost, r);
  h << cost.Finish();
  h << "<h2>Parameters over the iterations</h2>\n";
  SvgCanvas params(ParamColumns(r) * kParamWidth, kLegendHeight + ParamRows(r) * kParamHeight,
                   "params");
  DrawParameters(params, r);
  h << params.Finish();
  h << "<h2>Sequences</h2>\n";
  if (r.sequences.empty()) h << "<p class=\"muted\">no sequences recorded</p>\n";
  for (size_t i = 0; i < r.sequences.size() && i < sequence_pngs.size(); ++i) {
    h << "<h3>" << HtmlEscape(r.sequences[i].name) << "</h3>\n<img alt=\"sequence "
      << HtmlEscape(r.sequences[i].name) << "\" src=\"data:image/png;base64,"
      << Base64(sequence_pngs[i]) << "\">\n";
  }
  h << "<p class=\"muted\">written by mjsysid from result.yaml and result.h5; the plots are also "
       "in this folder as cost.png, parameters.png and seq_*.png</p>\n</body>\n</html>\n";
  return h.str();
}

// ---------------------------------------------------------------------------------------------
// files

// path.tmp-<pid>, then renamed over path
void WriteFileAtomically(const std::string& path, const std::string& bytes) {
  const std::string tmp = path + ".tmp-" + std::to_string(::getpid());
  bool ok = false;
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    out.close();
    ok = !out.fail();
  }
  const int err = errno;
  if (!ok || std::rename(tmp.c_str(), path.c_str()) != 0) {
    const int rename_err = ok ? errno : err;
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    throw ReportError(path + ": cannot write the file: " + std::strerror(rename_err));
  }
}

}  // namespace

// -----------------------------------------------------------------------------------------------

std::string SequenceFileName(const std::string& sequence_name) {
  std::string name;
  for (const char ch : sequence_name) {
    const auto c = static_cast<unsigned char>(ch);
    name += std::isalnum(c) || c == '_' || c == '.' || c == '-' ? ch : '_';
  }
  return "seq_" + name + ".png";
}

std::string CostPng(const FitResultFile& result) {
  RasterCanvas c(kCostWidth, kCostHeight);
  DrawCost(c, result);
  return EncodePng(c.image());
}

std::string ParametersPng(const FitResultFile& result) {
  RasterCanvas c(ParamColumns(result) * kParamWidth,
                 kLegendHeight + ParamRows(result) * kParamHeight);
  DrawParameters(c, result);
  return EncodePng(c.image());
}

std::string SequencePng(const FitResultFile&, const SequenceResult& sequence) {
  RasterCanvas c(kSeqWidth, kSeqHeaderHeight + SeqRows(sequence) * kSeqPanelHeight);
  DrawSequence(c, sequence);
  return EncodePng(c.image());
}

std::string ReportHtml(const FitResultFile& result) {
  std::vector<std::string> pngs;
  for (const SequenceResult& s : result.sequences) pngs.push_back(SequencePng(result, s));
  return Html(result, pngs);
}

int WriteReport(const FitResultFile& result, const std::string& dir, std::string* summary) {
  const auto start = std::chrono::steady_clock::now();
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec)) throw ReportError(dir + ": no such directory");
  const std::filesystem::path d(dir);

  // the plots, then the page that embeds the sequence plots
  std::vector<std::string> written;
  WriteFileAtomically((d / "cost.png").string(), CostPng(result));
  written.push_back("cost.png");
  WriteFileAtomically((d / "parameters.png").string(), ParametersPng(result));
  written.push_back("parameters.png");
  std::vector<std::string> pngs;
  std::set<std::string> names;
  for (const SequenceResult& s : result.sequences) {
    // two names that sanitize alike: _2, _3, ...
    std::string file = SequenceFileName(s.name);
    for (int k = 2; !names.insert(file).second; ++k) {
      file = SequenceFileName(s.name + "_" + std::to_string(k));
    }
    pngs.push_back(SequencePng(result, s));
    WriteFileAtomically((d / file).string(), pngs.back());
    written.push_back(file);
  }
  WriteFileAtomically((d / "report.html").string(), Html(result, pngs));
  written.insert(written.begin(), "report.html");

  if (summary != nullptr) {
    // a few lines for the terminal
    size_t unidentifiable = 0;
    std::string unid_names;
    for (const ParameterEstimate& p : result.parameters) {
      if (p.identifiable) continue;
      unid_names += (unidentifiable++ ? ", " : "") + p.name;
    }
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::ostringstream s;
    s << "report " << result.name << " (" << dir << ")\n"
      << "  status      " << result.status
      << (result.termination.empty() ? "" : " (" + result.termination + ")") << "\n"
      << "  cost        " << Num(result.initial_cost, 4) << " -> " << Num(result.final_cost, 4)
      << " in " << result.iterations << " iterations\n"
      << "  parameters  " << result.parameters.size();
    if (unidentifiable > 0) s << ", " << unidentifiable << " unidentifiable: " << unid_names;
    s << "\n  wrote       " << (d / "report.html").string();
    for (size_t i = 1; i < written.size(); ++i) s << (i == 1 ? " + " : ", ") << written[i];
    char buf[32];
    std::snprintf(buf, sizeof(buf), " in %.2f s\n", seconds);
    s << buf;
    *summary = s.str();
  }
  return static_cast<int>(written.size());
}

int WriteReport(const std::string& dir, std::string* summary) {
  return WriteReport(io::ReadResult(dir), dir, summary);
}

}  // namespace mjsysid::report
