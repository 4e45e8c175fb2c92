#include "tools/report/axes.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

namespace mjsysid::report {
namespace {

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

// 1, 2, 5 x 10^k steps, the one giving the number of ticks nearest `target` inside the axis
std::vector<double> LinearTicks(const Axis& a, int target, double* step) {
  const double span = a.hi - a.lo;
  const double mag = std::pow(10.0, std::floor(std::log10(span / target)));
  *step = mag;
  for (const double m : {2.0, 5.0, 10.0}) {
    if (std::abs(span / (m * mag) - target) < std::abs(span / *step - target)) *step = m * mag;
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

// a tick's label: as many decimals as the step needs; exponents for log axes and far values
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

}  // namespace

// ---------------------------------------------------------------------------------------------
// text

std::string Num(double v, int digits) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  char buf[40];
  std::snprintf(buf, sizeof(buf), "%.*g", digits, v);
  return buf;
}

std::string Shorten(const Canvas& c, const std::string& text, double width, bool bold) {
  if (c.TextWidth(text, bold) <= width) return text;
  std::string out = text;
  while (!out.empty() && c.TextWidth(out + "...", bold) > width) {
    // drop one utf-8 character
    size_t cut = out.size() - 1;
    while (cut > 0 && (static_cast<unsigned char>(out[cut]) & 0xC0) == 0x80) --cut;
    out.erase(cut);
  }
  return out + "...";
}

// ---------------------------------------------------------------------------------------------
// axes

void Range::Add(double v) {
  if (!std::isfinite(v)) return;
  lo = std::min(lo, v);
  hi = std::max(hi, v);
}

double Axis::Map(double v, double p0, double p1) const {
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

Axis LinearAxis(const Range& r, double pad) {
  if (r.empty()) return Axis{0, 1, false};
  const double lo = r.lo, hi = r.hi;
  if (hi - lo <= 1e-12 * std::max(std::abs(lo), std::abs(hi))) {
    // one value: a span of 10% of it around it (or +-1 around 0)
    const double half = lo == 0 ? 1 : 0.05 * std::abs(lo);
    return Axis{lo - half, hi + half, false};
  }
  const double span = hi - lo;
  return Axis{lo - pad * span, hi + pad * span, false};
}

Axis LogAxis(const Range& r) {
  if (r.empty() || r.lo <= 0) return Axis{0.1, 10, true};
  const double lo = std::pow(10.0, std::floor(std::log10(r.lo)));
  double hi = std::pow(10.0, std::ceil(std::log10(r.hi)));
  if (!(hi > lo)) hi = lo * 10;
  return Axis{lo, hi, true};
}

// ---------------------------------------------------------------------------------------------
// panels, lines, legends

Panel DrawPanel(Canvas& c, const Box& outer, const std::string& title, Rgb title_color,
                const Axis& x, const Axis& y, const std::string& xlabel, Rgb background,
                double min_left) {
  const double cap = c.CapHeight();

  // ticks and their labels first: the widest y label sets the left margin
  double xstep = 1, ystep = 1;
  const std::vector<double> xticks = x.log ? LogTicks(x) : LinearTicks(x, 6, &xstep);
  const std::vector<double> yticks = y.log ? LogTicks(y) : LinearTicks(y, 5, &ystep);
  std::vector<std::string> ylabels;
  double ylabel_width = 0;
  for (const double v : yticks) {
    ylabels.push_back(TickLabel(v, ystep, y.log));
    ylabel_width = std::max(ylabel_width, c.TextWidth(ylabels.back()));
  }

  // the plotting area: title above; x tick labels and the x label below
  Panel p;
  p.x = x;
  p.y = y;
  p.plot.x = std::round(outer.x + std::max(min_left, 12 + ylabel_width + 8));
  p.plot.y = std::round(outer.y + 10 + cap + 10);
  p.plot.w = std::round(outer.right() - 16 - p.plot.x);
  p.plot.h = std::round(outer.bottom() - 12 - cap - 8 - (xlabel.empty() ? 0 : cap + 10) - p.plot.y);

  // title, plot background, grid with tick labels, frame, x label
  c.Text(p.plot.x, outer.y + 10, Shorten(c, title, outer.right() - 8 - p.plot.x, true), title_color,
         Align::kLeft, true);
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
  c.Polyline({{l, t}, {r, t}, {r, b}, {l, b}, {l, t}}, kFrame, 1);
  if (!xlabel.empty()) {
    c.Text(p.plot.x + p.plot.w / 2, p.plot.bottom() + 8 + cap + 10, xlabel, kMuted, Align::kCenter);
  }
  return p;
}

void DrawSeries(Canvas& c, const Panel& p, const std::vector<double>& xs,
                const std::vector<double>& ys, Rgb color, double width, double dash,
                double marker) {
  std::vector<Point> points;
  for (size_t i = 0; i < xs.size() && i < ys.size(); ++i) {
    if (std::isfinite(ys[i])) points.push_back(p.Map(xs[i], ys[i]));  // NaN: not measured
  }
  c.Clip(p.plot);
  if (width > 0) c.Polyline(points, color, width, dash);
  if (marker > 0) {
    for (const Point& pt : points) c.Disk(pt, marker, color);
  }
  c.NoClip();
}

void DrawLegend(Canvas& c, double x, double y, const std::vector<LegendItem>& items) {
  const double mid = y + c.CapHeight() / 2;
  for (const LegendItem& item : items) {
    c.Line({x, mid}, {x + 30, mid}, item.color, 2.5, item.dash);
    if (item.marker) c.Disk({x + 15, mid}, 4, item.color);
    c.Text(x + 38, y, item.label, kInk, Align::kLeft);
    x += 38 + c.TextWidth(item.label) + 28;
  }
}

// ---------------------------------------------------------------------------------------------
// decimation

std::vector<Eigen::Index> Decimate(const Eigen::Ref<const Eigen::VectorXd>& y, int max_points) {
  const Eigen::Index n = y.size();
  std::vector<Eigen::Index> out;
  if (n <= std::max(max_points, 4)) {
    for (Eigen::Index i = 0; i < n; ++i) out.push_back(i);
    return out;
  }
  const Eigen::Index buckets = std::max(max_points, 4) / 2 - 1;
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

}  // namespace mjsysid::report
