// The report's interactive plots, drawn in the browser by the vendored dygraphs
// (tools/report/vendor_files.h): drag across a chart to zoom in on a window, double-click to zoom
// out, shift-drag to pan; the legend above each chart shows the values under the pointer. The
// page inlines the library once (InteractiveHead); each chart is a <div> and a call with its data.
// Every chart's Dygraph object is in the page's array `mjsysidCharts` (the browser test drives
// them).
//
// A sequence (SequenceCharts), per column (ColumnLabels: its sensor channels, fitted states
// included), side by side:
// - the signals: measured, simulated at the initial parameters and at the estimate (a fit in
//   segments: in one piece, and segment by segment, as the still plots);
// - the residual simulated - measured at the estimate (what the fit fitted: segment by segment for
//   a fit in segments), the band +-2 sigma shaded where the channel has a sigma, titled with the
//   channel's diagnostics (sysid/assess/residual_diagnostics.h: rms / sigma, lag-1 correlation,
//   correlation time, whiteness);
// then one chart of the logged inputs at their own times (LoggedInputs; held controls as steps),
// when there are any. The charts of one sequence share their time axis: zooming or panning one
// moves the others, double-clicking one resets them all.
// The residuals' autocorrelation (AutocorrelationCharts): per fitted sensor channel, pooled over
// the fitted sequences (PoolResidualsByChannel), lags 0 .. min(kAutocorrelationLags, a quarter of
// the longest sequence), the band +-1.96 / sqrt(n) shaded (white noise stays inside it at 95 % of
// the lags).
// Data: each line decimated to at most ChartIds::points samples (axes.h Decimate: peaks survive;
// kInteractivePoints, fewer on a page of many columns: PointsPerLine), a chart's rows the union of
// its lines' samples; NaN (not measured) is a gap; numbers to 6 significant digits. Every text is
// HTML-escaped; the data are JSON (nlohmann).
#pragma once

#include <Eigen/Core>
#include <limits>
#include <string>
#include <vector>

#include "sysid/io/result.h"
#include "tools/report/canvas.h"
#include "tools/report/logged.h"

namespace mjsysid::report {

inline constexpr int kInteractivePoints = 1500;
inline constexpr int kAutocorrelationLags = 200;
// a page's charts keep about this many samples in all (~40 bytes each): a page of many sequences
// and columns stays a few MB, each line at least kMinLinePoints
inline constexpr int kPageLinePoints = 200000, kMinLinePoints = 150;

// the samples per line for a page of `columns` plotted columns in all (4 lines each):
// kPageLinePoints / (4 columns), within [kMinLinePoints, kInteractivePoints]
int PointsPerLine(int columns);

// the library and the glue (<style> and <script> elements): once per page, before any chart
std::string InteractiveHead();

// Numbers the charts of one page ("chart-1", "chart-2", ...) and their time-axis groups; `points`:
// the samples each line keeps.
class ChartIds {
 public:
  explicit ChartIds(int points_per_line = kInteractivePoints) : points(points_per_line) {}
  std::string Next() { return "chart-" + std::to_string(++charts_); }
  std::string NextGroup() { return "group-" + std::to_string(++groups_); }
  int charts() const { return charts_; }
  const int points;

 private:
  int charts_ = 0, groups_ = 0;
};

// One chart: lines over a common increasing x (a time axis, or lags), each line one value per x
// (NaN: a gap); an optional shaded horizontal band; charts with the same group share their x
// axis. ChartHtml gives its caption, legend and plot <div>s and the call that draws it ("" without
// data), each line decimated to ids.points samples.
struct Line {
  std::string label;
  Eigen::VectorXd y;  // one value per x
  Rgb color;
  double width = 1.2;
  bool dashed = false, step = false;
};
struct Chart {
  std::string kind;   // the <div>'s class: "signal", "residual", "inputs", ... (for the tests)
  std::string title;  // HTML (escaped by the caller)
  std::string xlabel, ylabel;
  Eigen::VectorXd x;  // increasing
  std::vector<Line> lines;
  double band_lo = std::numeric_limits<double>::quiet_NaN();  // a shaded band (NaN: none)
  double band_hi = std::numeric_limits<double>::quiet_NaN();
  std::string band_color = "rgba(46,125,50,0.13)";
  bool points = false;
  std::string group;  // charts sharing the time axis ("": none)
};
std::string ChartHtml(const Chart& c, ChartIds& ids);

// a sequence's charts (see above); diagnostics: the result's residual diagnostics (matched to the
// columns by channel name; empty: none, e.g. a held-out sequence); inputs: its logged controls
// (no rows: no inputs chart)
std::string SequenceCharts(const SequenceResult& sequence,
                           const std::vector<ResidualDiagnostics>& diagnostics,
                           const LoggedInputs& inputs, ChartIds& ids);

// the autocorrelation charts of the fitted sequences' residuals (see above); "" when no channel
// has two measured samples
std::string AutocorrelationCharts(const std::vector<SequenceResult>& fitted,
                                  const std::vector<ResidualDiagnostics>& diagnostics,
                                  ChartIds& ids);

}  // namespace mjsysid::report
