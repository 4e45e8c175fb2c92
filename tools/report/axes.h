// The plotting kit of the report's figures: value ranges, linear and log axes with their ticks,
// panels (title, grid, frame, tick labels), data lines, legends, and the decimation of long lines.
//
// - Values map to pixels through a Panel: x grows to the right, y upwards (pixel y downwards).
// - Non-finite values are skipped by Range and break lines; values <= 0 on a log axis map to NaN.
#pragma once

#include <Eigen/Core>
#include <limits>
#include <string>
#include <vector>

#include "tools/report/canvas.h"

namespace mjsysid::report {

// palette
constexpr Rgb kWhite{255, 255, 255};
constexpr Rgb kInk{34, 34, 34};
constexpr Rgb kMuted{110, 110, 110};
constexpr Rgb kFrame{160, 160, 160};
constexpr Rgb kGrid{230, 230, 230};
constexpr Rgb kMeasured{165, 165, 165};
constexpr Rgb kBefore{31, 95, 191};
constexpr Rgb kAfter{214, 39, 40};
constexpr Rgb kSegments{240, 150, 60};  // a fit in segments, segment by segment
constexpr Rgb kTruth{30, 150, 60};
constexpr Rgb kUnidentifiable{253, 232, 232};
constexpr Rgb kAlert{198, 40, 40};

// "%.<digits>g"; inf, -inf, nan spelled out
std::string Num(double v, int digits = 6);

// the span of the finite values added
struct Range {
  double lo = std::numeric_limits<double>::infinity();
  double hi = -std::numeric_limits<double>::infinity();
  void Add(double v);
  bool empty() const { return !(lo <= hi); }
};

struct Axis {
  double lo = 0, hi = 1;
  bool log = false;
  // the pixel coordinate of v, p0 at lo and p1 at hi, within +-1e6; NaN for v <= 0 on a log axis
  double Map(double v, double p0, double p1) const;
};

// a linear axis over r with `pad` of its span added on both sides
Axis LinearAxis(const Range& r, double pad);

// a log axis over r (positive values) from one decade boundary to the next
Axis LogAxis(const Range& r);

// a panel's plotting area and axes
struct Panel {
  Box plot;
  Axis x, y;
  Point Map(double xv, double yv) const {
    return {x.Map(xv, plot.x, plot.right()), y.Map(yv, plot.bottom(), plot.y)};
  }
};

// Draws the title, background, grid, frame and tick labels of a panel filling `outer` and
// returns its plotting area. The y tick labels take what they need on the left, at least
// `min_left` px (panels side by side line up); `xlabel` (optional) goes under the x ticks.
Panel DrawPanel(Canvas& c, const Box& outer, const std::string& title, Rgb title_color,
                const Axis& x, const Axis& y, const std::string& xlabel, Rgb background,
                double min_left = 0);

// a line (dash > 0: dashed; width 0: none) and markers of radius `marker` (0: none) through the
// points (xs[i], ys[i]), clipped to the panel's plotting area
void DrawSeries(Canvas& c, const Panel& p, const std::vector<double>& xs,
                const std::vector<double>& ys, Rgb color, double width, double dash,
                double marker = 0);

struct LegendItem {
  std::string label;
  Rgb color;
  double dash = 0;
  bool marker = false;
};

// items side by side from (x, y) (the top of the text): a line sample, then the label
void DrawLegend(Canvas& c, double x, double y, const std::vector<LegendItem>& items);

// text cut to fit `width` px, "..." marking the cut
std::string Shorten(const Canvas& c, const std::string& text, double width, bool bold = false);

// lines of more points than this are decimated
constexpr int kMaxPoints = 2000;

// indices of the samples to plot: all up to max_points (at least 4), else the first and last sample
// and the minimum and maximum of each of max_points / 2 - 1 buckets, in order (peaks survive)
std::vector<Eigen::Index> Decimate(const Eigen::Ref<const Eigen::VectorXd>& y,
                                   int max_points = kMaxPoints);

}  // namespace mjsysid::report
