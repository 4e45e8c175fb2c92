#include "tools/report/plots.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "sysid/assess/metrics.h"
#include "tools/report/axes.h"

namespace mjsysid::report {
namespace {

using io::FitResultFile;
using mjsysid::ParameterEstimate;
using mjsysid::SequenceResult;

// panels side by side line up while their y labels fit in this width
constexpr double kLeftMargin = 92;
constexpr int kCostWidth = 900, kCostHeight = 440;
constexpr int kParamWidth = 400, kParamHeight = 260, kLegendHeight = 44;
constexpr int kSeqWidth = 1200, kSeqPanelHeight = 230, kSeqHeaderHeight = 76;

// the cost over the iterations, rejected steps marked
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

// the parameter panels: up to 3 per row
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

// the legend, then one panel per parameter
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

// the sensor column panels: two per row when there are more than 4
int SeqColumns(const SequenceResult& s) { return s.measured.cols() > 4 ? 2 : 1; }
int SeqRows(const SequenceResult& s) {
  const auto n = static_cast<int>(std::max<Eigen::Index>(1, s.measured.cols()));
  return (n + SeqColumns(s) - 1) / SeqColumns(s);
}

// a header with the legend, then one panel per sensor column
void DrawSequence(Canvas& c, const SequenceResult& s, bool held_out) {
  // header: what this is (a held-out sequence says so first), and the legend
  const Eigen::Index samples = s.time.size();
  std::string header = (held_out ? "validation (not fitted): sequence " : "sequence ") + s.name;
  if (!s.model.empty()) header += " (model " + s.model + ")";
  header += ", " + std::to_string(samples) + " samples";
  if (samples > 0)
    header += ", t = " + Num(s.time[0], 4) + " .. " + Num(s.time[samples - 1], 4) + " s";
  c.Text(14, 14, Shorten(c, header, kSeqWidth - 28), kInk, Align::kLeft);
  // a fit in segments: the fitted line is the estimate in one piece, the segments' beside it
  const bool segmented = s.simulated_one_piece.rows() == samples && samples > 0;
  std::vector<LegendItem> legend = {{"measured", kMeasured, 0, false},
                                    {"simulated, initial parameters", kBefore, 6, false}};
  if (segmented) {
    legend.push_back({"fitted, segment by segment", kSegments, 3, false});
    legend.push_back({"fitted, in one piece", kAfter, 0, false});
  } else {
    legend.push_back({"simulated, fitted parameters", kAfter, 0, false});
  }
  DrawLegend(c, 14, 14 + c.CapHeight() + 16, legend);
  const RowMatrix& fitted = segmented ? s.simulated_one_piece : s.simulated_final;

  // each panel's label with its % fit at the start and at the estimate (sysid/assess/metrics.h)
  std::vector<std::string> labels = ColumnLabels(s);
  for (size_t j = 0; j < labels.size() && j < s.channel_fits.size(); ++j) {
    const ChannelFit& f = s.channel_fits[j];
    if (std::isfinite(f.fit_initial) && std::isfinite(f.fit_final)) {
      labels[j] += "   fit " + Num(f.fit_initial, 3) + " % -> " + Num(f.fit_final, 3) + " %";
    }
  }
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
      if (segmented) inner.Add(fitted(k, j));
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
    std::vector<std::pair<const RowMatrix*, Rgb>> lines = {{&s.measured, kMeasured},
                                                           {&s.simulated_initial, kBefore}};
    if (segmented) lines.push_back({&s.simulated_final, kSegments});
    lines.push_back({&fitted, kAfter});
    for (const auto& [m, color] : lines) {
      const Eigen::VectorXd y = m->col(j);
      std::vector<double> xs, ys;
      for (const Eigen::Index k : Decimate(y)) {
        xs.push_back(s.time[k]);
        ys.push_back(y[k]);
      }
      const bool measured = m == &s.measured;
      // measured: a wide light band under the simulations
      const double dash =
          m == &s.simulated_initial ? 6 : (segmented && m == &s.simulated_final ? 3 : 0);
      DrawSeries(c, p, xs, ys, color, measured ? 3 : 1.6, dash, samples == 1 ? 3 : 0);
    }
  }
}

}  // namespace

std::vector<std::string> ColumnLabels(const SequenceResult& s) {
  std::vector<std::string> out = ChannelNames(s);
  out.resize(std::min<size_t>(out.size(), static_cast<size_t>(s.measured.cols())));
  while (static_cast<Eigen::Index>(out.size()) < s.measured.cols()) {
    out.push_back("column " + std::to_string(out.size()));
  }
  return out;
}

Figure CostFigure(const FitResultFile& result) {
  return {kCostWidth, kCostHeight, [&result](Canvas& c) { DrawCost(c, result); }};
}

Figure ParametersFigure(const FitResultFile& result) {
  return {ParamColumns(result) * kParamWidth, kLegendHeight + ParamRows(result) * kParamHeight,
          [&result](Canvas& c) { DrawParameters(c, result); }};
}

Figure SequenceFigure(const SequenceResult& sequence, bool held_out) {
  return {kSeqWidth, kSeqHeaderHeight + SeqRows(sequence) * kSeqPanelHeight,
          [&sequence, held_out](Canvas& c) { DrawSequence(c, sequence, held_out); }};
}

}  // namespace mjsysid::report
